"""fitode: the unknown constants of a known ODE, from a video."""
import os as _os

__version__ = "0.1.0"

# FFmpeg inside OpenCV prints its own errors on stderr for unreadable files; fitode reports
# those itself in one line, so silence it before any module opens a video.
_os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

from fitode.errors import (CodegenError, ConfigError, EquationError, FitodeError,  # noqa: E402
                           NonFiniteError, ParameterError, TrainingError)


def fit(*args, **kwargs):
    """See fitode.api.fit (imported lazily so `import fitode` does not load torch)."""
    from fitode.api import fit as _fit
    return _fit(*args, **kwargs)


def __getattr__(name):
    if name == "FitResult":
        from fitode.train.result import FitResult
        return FitResult
    raise AttributeError(name)
