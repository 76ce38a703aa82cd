"""fitode: the unknown constants of a known ODE, from a video."""
import os as _os

from fitode._version import __version__  # noqa: E402,F401

# FFmpeg inside OpenCV prints its own errors on stderr for unreadable files; fitode reports
# those itself in one line, so silence it before any module opens a video.
_os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

from fitode.errors import (CodegenError, ConfigError, EquationError, FitodeError,  # noqa: E402
                           NonFiniteError, ParameterError, TrainingError)


from fitode.fitting import fit  # noqa: E402 - torch-free; imports fitode.api when called


def __getattr__(name):
    if name in ("Result", "FitResult"):  # FitResult: the name before Result had its verbs
        from fitode.result import Result
        return Result
    raise AttributeError(name)
