"""`fitode.fit`: the public API, on a video path or on arrays of frames.

Torch-free at import (fitode.api, which needs torch, is imported when fit is called), so that
`import fitode` stays light and `help(fitode.fit)` shows this signature and docstring.
"""
from __future__ import annotations

import math
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
        time_offset: float = 0.0, callback: Callback | None = None, progress: bool = True,
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
    options: any TrainConfig field (restarts, max_steps, min_steps, window, integrator, encoder,
        light, seed, device, threads, lr, ...).
    Every bad option raises a fitode.ConfigError (or another FitodeError) naming it, before any work.
    """
    from fitode import api

    if (start is not None or end is not None) and "stretch" not in options:
        options["stretch"] = False  # the user chose the frames: no stretch is looked for
    reqs = api.requests(eq=eq, system=system, eq_file=eq_file, const=const, free=free, init=init, params=params,
                        prior=prior, train_fraction=train_fraction, observe=observe, calibrate=calibrate, scale=scale,
                        **options)
    req = reqs[0]
    video = dict(fps=fps, start=start, end=end, roi=roi, size=size, color=color, stride=stride, mask=mask)
    clip = None
    frames_path = frames
    if isinstance(frames, (str, os.PathLike)):
        clip, dt, time_offset = _read_path(frames, video, dt, time_offset, req, progress)
        frames = clip.frames
    else:
        given = [k for k in VIDEO_OPTIONS if video[k] not in (None, False)]
        if given:
            raise ConfigError(f"{', '.join(given)}: video options apply to a video path; frames given as an "
                              "array are used as they are (crop, resize or subsample them before)")
    x = api.as_frames(frames)
    from fitode.pipeline import rate_std
    rate = rate_std(fps) if clip is not None else 0.0  # an array's dt is the user's
    track = None if clip is None else clip.track
    from fitode.measurement import geometry
    where = None if clip is None else geometry(clip)
    plan = api.plan(req, x, dt, track=track, geometry=where)
    if clip is not None:  # as `fitode VIDEO` reads it: light from sRGB in colour, a level in more detail
        from fitode.pipeline import read_again
        clip, time_offset, plan = read_again(frames_path, _read_options(video), req, clip, time_offset, plan,
                                             progress=progress)
        x, track, where = api.as_frames(clip.frames), clip.track, geometry(clip)
    measurement = api.measure(plan, x)  # what cannot be measured fails before any fit
    if len(reqs) > 1:
        from fitode.compare import compare
        comparison = compare(reqs, x, dt, track=track, geometry=where, time_offset=time_offset, callback=callback, progress=progress,
                             rate_std=rate, first_plan=plan)
        result = comparison.result
        result.meta["comparison"] = comparison.to_dict()
    else:
        from fitode.interrupted import Stopped
        try:
            result = api.execute(req, plan, x, time_offset=time_offset, callback=callback, progress=progress,
                                 rate_std=rate, measurement=measurement)
        except Stopped as stop:  # Ctrl-C after training: the estimates, marked (result.meta["stopped"])
            result = stop.result
    if clip is not None:  # what was measured, in the video's pixels as `fitode VIDEO` writes it
        from fitode.pipeline import source_measurement
        source_measurement(result, clip)
    from fitode.result import Result
    return Result.of(result)


def _read_path(path, video: dict[str, Any], dt, time_offset, req, progress: bool):
    """The clip, dt and time offset of a video path, read as `fitode VIDEO` reads it."""
    from fitode.pipeline import read_clip

    if time_offset:
        raise ConfigError("time_offset is for frames given as an array; a path's first frame is at its start")
    clip, t0 = read_clip(path, _read_options(video), req.calibration, progress=progress)
    if dt is not None and not (isinstance(dt, (int, float)) and math.isclose(dt, clip.dt, rel_tol=1e-6)):
        raise ConfigError(f"dt={dt!r} disagrees with the clip's {clip.dt:g} s (stride {clip.stride} / "
                          f"{clip.fps:g} fps); leave dt out for a path, or set fps")
    return clip, float(clip.dt), t0


def _read_options(video: dict[str, Any]):
    from fitode.pipeline import ReadOptions
    return ReadOptions(**{**video, "stride": "auto" if video["stride"] is None else video["stride"]})
