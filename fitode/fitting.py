"""`fitode.fit`: the public API, on a video path or on arrays of frames.

Torch-free at import (fitode.api, which needs torch, is imported when fit is called), so that
`import fitode` stays light and `help(fitode.fit)` shows this signature and docstring.
"""
from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

from fitode.errors import ConfigError

if TYPE_CHECKING:
    from fitode.eqparse import OdeSystem, ParamSpec
    from fitode.train.observe import ObservationModel
    from fitode.result import Result
    from fitode.train.trainer import Callback

# read_video's options: they apply to a video path, not to frames given as an array
VIDEO_OPTIONS = ("fps", "start", "end", "roi", "size", "color", "stride", "mask")


def fit(frames: Any, dt: float | None = None, *, eq: str | Sequence[str] | None = None, system: str | OdeSystem | None = None,
        eq_file: str | None = None, const: Mapping[str, float] | None = None, free: Iterable[str] = (),
        init: Mapping[str, float] | None = None, params: Mapping[str, ParamSpec] | None = None,
        prior: tuple[float, float] | None = None, train_fraction: float = 1.0,
        observe: str | Mapping[str, str] | ObservationModel | None = None, calibrate: str | None = None,
        scale=None, fps: float | None = None, start: float | None = None, end: float | None = None,
        roi: tuple[int, int, int, int] | str | None = None, size: tuple[int, int] | str | None = None,
        color: bool = False, stride: int | str | None = None, mask: str | None = None,
        time_offset: float = 0.0, callback: Callback | None = None, progress: bool | None = None,
        **options: Any) -> Result:
    """Estimate the learnable constants of an equation from a video or a frame sequence.

    frames: a video path (file, folder of images or .npy, as `fitode VIDEO` takes), read with
        the command line's reader and checks, or frames (T, H, W), (T, C, H, W) or (T, H, W, C)
        with C in {1, 3}, numpy or torch, any range.
    dt: seconds between consecutive frames; required for frames, taken from the clip for a path
        (given there, it must agree with the clip's stride / fps).
    eq | system | eq_file: the equation as text ("x'' = -g/L*sin(x) - z*x'"), a shipped system's
        name (or an OdeSystem), or an equation file (TOML). Several candidate equations (a list
        of texts as eq, or a file with `alternatives`) are compared (fitode.compare): each fitted
        to the same measured path, ranked by blocked cross-validation along time; the result is
        the preferred candidate's (the first's where the clip cannot tell them apart), and
        result.meta["comparison"] holds every candidate's constants, intervals, held-out error
        and verdict, "preferred" (the equation as given, or None) and "reason".
    const: fix constants {"g": 9.81}; free: known constants to learn (["g"]); init: starting
        values for every restart; prior: (mean, std) of the latent, overriding the file's.
    observe: "auto" (None), a model of fitode.train.observe.catalog ("position", "brightness",
        ...), one per state ("x=position;y=size"), or an ObservationModel instance.
    calibrate: known values of states, "h(0)=0.07; h(25)=0.01" (seconds of the video): scale-
        dependent constants come back in physical units.
    scale: a scale stick ((x1, y1), (x2, y2), D): two points of the source frame (pixels, x right,
        y down) D metres apart (D a number, (D, U) or "D±U"); or --scale's text. With it a measured
        position, level or size is in metres (y up) and its constants in SI units, their intervals
        carrying the stick's uncertainty; without it, in source pixels (px/s^2).
    fps, start, end, roi, size, color, stride, mask: for a path only, as --fps, --start, --end,
        --roi (x, y, w, h or "X,Y,W,H"), --size ((H, W) or "WxH"), --color, --stride (K or
        "auto", the default) and --mask; a path with these options fits the same frames, and
        gives the same numbers, as `fitode VIDEO` with the same flags.
    time_offset: video time of the first frame, for calibrate's times (frames only: a path's
        comes from start).
    progress: progress bars on stderr; None (the default): only where stderr is a terminal or a
        notebook shows them, never into a log file or a pipe; True or False: as asked.
    options: any TrainConfig field (restarts, max_steps, min_steps, window, integrator, encoder,
        light, seed, device, threads, lr, ...).
    Every bad option raises a fitode.ConfigError (or another FitodeError) naming it, before any work.
    """
    from fitode import api

    if progress is None:
        progress = _terminal()
    if (start is not None or end is not None) and "stretch" not in options:
        options["stretch"] = False  # the user chose the frames: no stretch is looked for
    reqs = api.requests(eq=eq, system=system, eq_file=eq_file, const=const, free=free, init=init, params=params,
                        prior=prior, train_fraction=train_fraction, observe=observe, calibrate=calibrate, scale=scale,
                        **options)
    video = dict(fps=fps, start=start, end=end, roi=roi, size=size, color=color, stride=stride, mask=mask)
    from fitode.interrupted import Stopped
    from fitode.pipeline import fit_staged, measure_array, measure_clip, rate_std

    # the one front door's stages, as `fitode VIDEO` and fitode batch run them
    if isinstance(frames, (str, os.PathLike)):
        if time_offset:
            raise ConfigError("time_offset is for frames given as an array; a path's first frame is at its start")
        staged, rate = measure_clip(reqs, frames, _read_options(video), progress=progress, dt=dt), rate_std(fps)
    else:
        given = [k for k in VIDEO_OPTIONS if video[k] not in (None, False)]
        if given:
            raise ConfigError(f"{', '.join(given)}: video options apply to a video path; frames given as an "
                              "array are used as they are (crop, resize or subsample them before)")
        staged, rate = measure_array(reqs, frames, dt, time_offset), 0.0  # an array's dt is the user's
    try:
        result, _, _, comparison = fit_staged(reqs, staged, rate=rate, callback=callback, progress=progress)
    except Stopped as stop:  # Ctrl-C after training: the estimates, marked (result.meta["stopped"])
        if len(reqs) > 1:
            raise
        result, comparison = stop.result, None
        if staged.clip is not None:
            from fitode.pipeline import source_measurement
            source_measurement(result, staged.clip)
    if comparison is not None:
        result.meta["comparison"] = comparison.to_dict()
    from fitode.result import Result
    return Result.of(result)


def _terminal() -> bool:
    """stderr is a terminal, or a Jupyter kernel draws the bars (its stderr is no tty)."""
    import sys
    return bool(getattr(sys.stderr, "isatty", lambda: False)()) or "ipykernel" in sys.modules


def _read_options(video: dict[str, Any]):
    from fitode.pipeline import ReadOptions
    return ReadOptions(**{**video, "stride": "auto" if video["stride"] is None else video["stride"]})
