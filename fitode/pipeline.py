"""The single-video job behind `fitode VIDEO --eq ...` (and each item of `fitode batch`).

run_video reads the video, says what it understood, fits, calibrates when asked, and writes
an output folder: result.json (the report), fit.json (the full FitResult with every run's
history, reloadable with FitResult.load), estimates.csv and track.csv (fitode.tables), latent.png,
frames.png, track.png (what was measured, drawn on the frames), and where an encoder was trained
params.png and loss.png.
An interrupted run (Ctrl-C, SIGTERM) or one where every restart failed still leaves a folder, with
result.json marked "interrupted" (with the "stage" it stopped in: fitode.interrupted) or "failed",
estimates.csv (the estimates wherever a fit finished) and whatever plots its data allow.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

from fitode.errors import FitodeError
from fitode.interrupted import Stopped, mark_report, reached
from fitode.measurement import geometry
from fitode.output import _check_out_dir, _make_out_dir, _plots_for_result, _try_plot
from fitode.train.history import History  # torch-free, like everything this module imports at the top



class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM after a fit finished, once the folder is written (status "interrupted",
    "stage" where it stopped); .outcome has it."""

    def __init__(self, outcome: "RunOutcome"):
        super().__init__("interrupted")
        self.outcome = outcome


@dataclass
class RunOutcome:
    """What run_video returns. report is exactly what result.json holds."""

    result: Any  # fitode.result.Result (not imported here so `import fitode.pipeline` stays light)
    out_dir: Path
    report: dict[str, Any]
    warnings: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class ReadOptions:
    """What to read of a video: the keywords of fitode.video.read_video (roi, size and stride may be
    given as the text the command line takes)."""

    fps: float | None = None
    start: float | None = None
    end: float | None = None
    roi: Any = None
    size: Any = None
    color: bool = False
    stride: int | str = "auto"
    mask: Any = None

    def as_dict(self) -> dict[str, Any]:
        return {f: getattr(self, f) for f in READ_OPTIONS}


READ_OPTIONS = ("fps", "start", "end", "roi", "size", "color", "stride", "mask")


def run_job(video: str | Path, out_dir: str | Path | None = None, *, progress: bool = False,
            log: Callable[[str], None] | None = print, callback=None, plots: bool = True, **options) -> RunOutcome:
    """run_video with its options flat, as a batch manifest's row names them: the keywords of
    ReadOptions go to the reader, every other one to fitode.api.request (fitode.fit's keywords)."""
    read = ReadOptions(**{k: options.pop(k) for k in READ_OPTIONS if k in options})
    return run_video(video, out_dir, read=read, fit=options, progress=progress, log=log, callback=callback,
                     plots=plots)


@dataclass
class Staged:
    """A clip read, planned and measured: what the fit takes (measure_clip, measure_array).

    clip: the fitode.video.Clip read (None for frames given as an array); t0: the video time of
    its first frame; frames: float (T, C, H, W); dt: seconds between them; plan: the first
    candidate's FitPlan; measurement: its fitode.train.measure.Measurement; geometry: where the
    frames lie in the source (fitode.measurement.FrameGeometry; None for an array)."""

    clip: Any
    t0: float
    frames: Any
    dt: float
    plan: Any
    measurement: Any
    geometry: Any = None
    array_track: Any = None  # the reader's track of frames given as an array (a clip's is its own)

    @property
    def track(self):
        return self.array_track if self.clip is None else self.clip.track


def measure_clip(reqs, video, read: ReadOptions, *, progress: bool = False, dt: float | None = None) -> Staged:
    """read -> plan -> measure for a video path, as every front door does it (`fitode VIDEO`,
    fitode.fit, fitode batch): the clip read again where the plan reads it better (read_again), and
    what cannot be measured failing here, in one line, before any fit or output. dt: a dt the
    caller was given, which must agree with the clip's."""
    import math

    from fitode import api
    from fitode.errors import ConfigError

    req = reqs[0]
    clip, t0 = read_clip(video, read, req.calibration, progress=progress)
    if dt is not None and not (isinstance(dt, (int, float)) and math.isclose(dt, clip.dt, rel_tol=1e-6)):
        raise ConfigError(f"dt={dt!r} disagrees with the clip's {clip.dt:g} s (stride {clip.stride} / "
                          f"{clip.fps:g} fps); leave dt out for a path, or set fps")
    plan = api.plan(req, api.as_frames(clip.frames), clip.dt, track=clip.track, geometry=geometry(clip))
    clip, t0, plan = in_view(video, read, req, clip, t0, plan, progress=progress)
    clip, t0, plan = read_again(video, read, req, clip, t0, plan, progress=progress)
    frames = api.as_frames(clip.frames)
    return Staged(clip, t0, frames, float(clip.dt), plan, api.measure(plan, frames), geometry(clip))


def measure_array(reqs, frames, dt: float, time_offset: float = 0.0) -> Staged:
    """plan -> measure for frames given as an array (their pixels are the source's)."""
    from fitode import api
    from fitode.video.track import track_array

    x = api.as_frames(frames)
    track = track_array(x.numpy())
    plan = api.plan(reqs[0], x, dt, track=track)
    return Staged(None, float(time_offset), x, float(dt), plan, api.measure(plan, x), array_track=track)


def fit_staged(reqs, staged: Staged, *, rate: float = 0.0, callback=None, progress: bool = False,
               log: Callable[[str], None] | None = None):
    """fit -> assess for a staged clip: (result, request, plan, comparison), the result of the one
    candidate or of the one a comparison prefers (fitode.compare; comparison None for one), what
    was measured mapped to the source's pixels where there is a clip."""
    from fitode import api

    comparison = None
    if len(reqs) > 1:
        from fitode.compare import compare
        comparison = compare(reqs, staged.frames, staged.dt, track=staged.track, geometry=staged.geometry,
                             time_offset=staged.t0, callback=callback, progress=progress, rate_std=rate, log=log,
                             first_plan=staged.plan)
        chosen = comparison.candidates[comparison.chosen]
        result, req, plan = chosen.result, chosen.request, chosen.plan
    else:
        from fitode.objects import another_object

        req, plan = reqs[0], staged.plan
        result = api.execute(req, plan, staged.frames, time_offset=staged.t0, callback=callback, progress=progress,
                             rate_std=rate, measurement=staged.measurement)

        def fit(other):  # another object's request, fitted as the first was
            other_plan = api.plan(other, staged.frames, staged.dt, track=staged.track, geometry=staged.geometry)
            return other_plan, api.execute(other, other_plan, staged.frames, time_offset=staged.t0,
                                           callback=callback, progress=progress, rate_std=rate)

        other = another_object(req, plan, result, fit, log=log)
        if other is not None:
            result, req, plan = other
    if staged.clip is not None:  # what was measured, in the video's pixels
        source_measurement(result, staged.clip)
    return result, req, plan, comparison


def run_video(video: str | Path, out_dir: str | Path | None = None, *, read: ReadOptions = ReadOptions(),
              fit: Mapping[str, Any], progress: bool = False, log: Callable[[str], None] | None = print,
              callback=None, plots: bool = True) -> RunOutcome:
    """Fit one video and write its output folder; see the module docstring.

    read: what to read of the video. fit: the keyword arguments of fitode.fit besides the frames
    (eq/eq_file/system, const, free, init, prior, observe, calibrate, train_fraction and the
    training options). out_dir None makes a new folder fitode-runs/<video-stem>-<YYYYmmdd-HHMMSS>[-N]
    under the current directory; a given out_dir must not exist or be empty. log receives the
    human text (what was understood, per-run summaries, calibration, where files went); None
    silences it. callback is called with every StepInfo. plots False: no pictures (the numbers and
    tables only; a batch of many clips saves the seconds each one's pictures cost).
    Raises FitodeError (one-line message) for any bad input; KeyboardInterrupt propagates after
    the partial folder is written (RunInterrupted, carrying the RunOutcome, when the trainer
    returned what it had).
    """
    target = _check_out_dir(out_dir)  # first: an unwritable --out costs not even the import of torch
    from fitode import api
    from fitode import report as rep

    say = log if log is not None else (lambda _line: None)

    # Cheap checks first: a typo in an option, the equation or the calibration must not cost a video decode.
    if (read.start is not None or read.end is not None) and "stretch" not in fit:
        fit = {**fit, "stretch": False}  # the user chose the frames: no stretch is looked for
    reqs = api.requests(**fit)  # one per candidate equation (several: a comparison, fitode.compare)
    req = reqs[0]
    ode, spec = req.system, req.spec
    analysis = rep.analysis_dict(rep.identifiability(ode))

    # read -> plan -> measure: what cannot be measured fails here, before the header and the folder
    staged = measure_clip(reqs, video, read, progress=progress)
    clip, t0, plan = staged.clip, staged.t0, staged.plan
    for line in rep.understanding_lines(ode, spec, analysis, clip, plan):
        say(line)

    folder = _make_out_dir(target, Path(str(video)).stem)
    recorder = _Recorder(ode.learnable, callback)
    options = {**read.as_dict(), "mask": None if read.mask is None else str(read.mask),
               "calibrate": fit.get("calibrate")}
    report = rep.base_report(video, clip, ode, spec, analysis, plan, req.train_fraction, folder, options, t0)
    rep.write_json(report, folder / "result.json")  # "running": even a hard kill leaves a marked folder
    plots_done: list[str] = []
    from fitode import plots as plots_module

    comparison = None
    try:
        # inside the try: a signal while it is drawn still leaves the folder marked interrupted
        if plots:
            _try_plot(plots_module.plot_frames, folder / "frames.png", clip.frames, clip.dt, t0=t0,
                      plots_done=plots_done)
        result, req, plan, comparison = fit_staged(reqs, staged, rate=rate_std(read.fps), callback=recorder,
                                                   progress=progress, log=say)
        if plan is not staged.plan:  # the report describes the candidate, or the object, whose numbers it gives
            ode, spec = req.system, req.spec
            analysis = rep.analysis_dict(rep.identifiability(ode))
            report = {**rep.base_report(video, clip, ode, spec, analysis, plan, req.train_fraction, folder,
                                        options, t0), "created": report["created"]}
    except KeyboardInterrupt as exc:
        if not (isinstance(exc, Stopped) and len(reqs) == 1):  # no fit finished (of a comparison: not all)
            stage = "training" if len(reqs) == 1 else "comparison"
            _write_partial(report, recorder, folder, "interrupted", f"interrupted during the {stage}",
                           plots_done, stage=stage, plots=plots)
            say(f"interrupted: partial results in {folder}")
            raise
        result = exc.result  # the fit finished: its estimates are kept (fitode.interrupted)
        source_measurement(result, clip)
    except FitodeError as exc:
        _write_partial(report, recorder, folder, "failed", str(exc), plots_done, plots=plots)
        raise

    interrupted = bool(result.meta.get("interrupted"))
    for line in rep.run_lines(result):
        say(line)
    for line in _slow_motion_hint(result, clip):
        say(line)
        result.warnings.append(line)
    for line in (result.calibration or {}).get("lines", []):
        say(line)
    rep.complete_report(report, result, analysis, t0)
    # the source video's frame numbers, as track.png labels them (repeats dropped, holes filled)
    report["trajectory"]["frames"] = [int(f) for f in clip.frame_indices]
    if comparison is not None:
        report["comparison"] = comparison.to_dict()
        result.meta["comparison"] = report["comparison"]
    mark_report(report, result)
    if interrupted and req.calibration and result.calibration is None:
        report["warnings"].append(f"--calibrate was not applied: the {report['stage']} was interrupted")
    result.meta.update({"input": report["input"]})
    # the numbers first: an interruption while drawing loses only pictures
    from fitode.tables import write_run_tables
    result.save_json(folder / "fit.json")
    tables = write_run_tables(report, folder)
    report["files"] = sorted(["result.json", "fit.json", *plots_done, *tables])
    rep.write_json(report, folder / "result.json")
    try:
        if plots:
            reached("pictures")
            report["warnings"] += _plots_for_result(folder, result, report, plots_done, t0)
            warning = _try_plot(plot_track, folder / "track.png", result, clip, video, t0, plots_done=plots_done)
            report["warnings"] += [warning] if warning else []
    except KeyboardInterrupt:
        interrupted = True
        if report["status"] != "interrupted":
            report["status"], report["stage"] = "interrupted", "pictures"
            report["error"] = "interrupted while drawing the pictures"
    report["files"] = sorted(["result.json", "fit.json", *plots_done, *tables])
    rep.write_json(report, folder / "result.json")
    say(f"wrote {folder}/ ({', '.join(report['files'])})")
    from fitode.result import Result
    outcome = RunOutcome(result=Result.of(result), out_dir=folder, report=report, warnings=list(report["warnings"]))
    if interrupted:
        raise RunInterrupted(outcome)
    return outcome


def rate_std(fps: float | None) -> float:
    """The frame rate's relative uncertainty for the interval: none where the user gave it."""
    from fitode.train.interval import RATE_CONTAINER_STD, RATE_GIVEN_STD
    return RATE_GIVEN_STD if fps else RATE_CONTAINER_STD


# ---------------------------------------------------------------------------------------------
def read_clip(video: str | Path, read: ReadOptions = ReadOptions(), calibration: tuple = (), *,
              progress: bool = False, track: bool = True) -> tuple[Any, float]:
    """The clip a fit of `video` uses (fitode.video.Clip) and the video time of its first frame
    (what `start` skipped), with the checks of `fitode VIDEO`: at least one frame, calibration
    times inside the clip. fitode.fit reads a path through here too, so both fit the same frames.
    track: False to leave the object's track out (Clip.track None): a read again of the same frames."""
    clip = _read(video, **read.as_dict(), progress=progress, track=track)
    n_frames = int(clip.frames.shape[0])
    if n_frames == 0:
        raise FitodeError(f"{video}: no frames to fit (check --start/--end)")
    t0 = float(clip.times[0])  # the first frame's real time: repeats dropped and timestamps honoured
    if calibration:
        from fitode.calibrate import check_times
        check_times(calibration, t0, t0 + (n_frames - 1) * clip.dt, slack=0.5 * clip.dt)
    return clip, t0


# the share of the frames the object may be unseen in where it is in view (the observations that
# read a place refuse more: observe.position, observe.angle), and the longest gap in its sighting
UNSEEN_MAX = 0.1


def in_view(video, read: ReadOptions, req, clip, t0: float, plan, *, progress: bool = False):
    """(clip, t0, plan): the clip read again where the object is whole in view (view_span), where
    the plan reads a place (position, angle) and the object enters the view after the first frame
    or leaves it before the last (a puck that slides in from the edge and out again, a cart that
    leaves the view); an end the user gave (--start, --end) stays theirs. Said in a note of the clip."""
    from dataclasses import replace

    from fitode import api
    from fitode.train.observe.angle import AngleObservation
    from fitode.train.observe.position import PositionObservation

    track, n = clip.track, int(clip.frames.shape[0])
    if track is None or len(track) != n or not any(
            isinstance(p, (PositionObservation, AngleObservation)) and getattr(p, "object", None) is None
            for p in _observation_parts(plan)):
        return clip, t0, plan
    if any(isinstance(p, AngleObservation) for p in _observation_parts(plan)):
        # a swing the change reads on its string in some frames jumps between the string and the bob;
        # read on one arc (as the angle observation reads it), its run of frames is not cut at every
        # jump, nor its lowest point, near the frame's edge, taken for the bob entering the view
        from fitode.train.observe.circle import on_one_radius
        track = replace(track, xy=on_one_radius(track.xy)[0])
    box = clip.roi if clip.roi else (0, 0, clip.source_size[1], clip.source_size[0])
    span = view_span(track, box, start_given=read.start is not None, end_given=read.end is not None)
    if span is None:
        return clip, t0, plan
    a, b = span
    index = clip.frame_indices
    start = read.start if read.start is not None else float(index[a]) / clip.fps
    end = read.end if read.end is not None else float(index[b - 1] + 0.5) / clip.fps
    seen, t1 = read_clip(video, replace(read, start=start, end=end, stride=clip.stride), req.calibration,
                         progress=progress)
    if seen.track is not None:
        seen.track.enters, seen.track.leaves = a > 0, b < n
    where = " and ".join(w for w, cut in (("enters", a > 0), ("leaves", b < n)) if cut) + " the view"
    seen.notes.append(f"the object is in view from {t0 + a * clip.dt:.3f} s to {t0 + (b - 1) * clip.dt:.3f} s "
                      f"only (it {where}; {n - (b - a)} of {n} frames outside): the clip is read and fitted "
                      "there (--start/--end choose otherwise)")
    return seen, t1, api.plan(req, api.as_frames(seen.frames), seen.dt, track=seen.track, geometry=geometry(seen))


def view_span(track, box: tuple, *, start_given: bool = False, end_given: bool = False) -> tuple[int, int] | None:
    """[a, b): the frames a track (train/observe/track.Track) sees the object whole in the view
    box (x, y, w, h in its pixels) in, where it enters the view after the clip's first frame or
    leaves it before the last; None where it does neither, where it is unseen in more than
    UNSEEN_MAX of [a, b) (the observation then says so), or where [a, b) is too short to fit.
    start_given, end_given: the user chose that end (--start, --end), which stays theirs.

    The frames the object is seen in are the run of them with the most, no gap longer than
    UNSEEN_MAX of the clip and no step longer than 3 times the median step or its radius (noise
    seen before it came or after it left is not it). It enters the view where that run starts
    after the first frame at the edge of the box (within twice its radius and a frame's step: an
    object that is unseen because it stands still, merged into the static scene, is not entering
    from the middle of the view), and leaves it likewise; the frames where its centre lies nearer
    an edge than its radius (from its mean area) are cut too: part of it is cut off and its
    centroid lags the object's (a puck 8 px in radius entering at 4 px a frame: 3 frames, which
    moved its speed 0.5% against a 95% interval of 0.36%)."""
    import numpy as np

    from fitode.train.stretch import MIN_SEED

    xy, n = track.xy, len(track)
    r = float(np.sqrt(max(track.area, 1.0) / np.pi)) + 1.0
    step = np.hypot(*np.diff(xy, axis=0).T)  # from one frame to the next, where both are seen
    typical = float(np.nanmedian(step)) if np.isfinite(step).any() else 0.0
    a, b = track.in_view(gap=max(1, int(UNSEEN_MAX * n)), far=3.0 * max(typical, r))
    if b <= a:
        return None
    x0, y0, w, h = box

    def margin(p) -> float:  # how far inside the box a point is (NaN where unseen)
        return float(min(p[0] - x0, x0 + w - 0.5 - p[0], p[1] - y0, y0 + h - 0.5 - p[1]))

    edge = 2 * r + 1 + typical
    enters = a > 0 and not start_given and margin(xy[a]) <= edge
    leaves = b < n and not end_given and margin(xy[b - 1]) <= edge
    if not (enters or leaves):
        return None
    a, b = (a if enters else 0), (b if leaves else n)
    while enters and a < b and not margin(xy[a]) >= r - 0.5:
        a += 1
    while leaves and b > a and not margin(xy[b - 1]) >= r - 0.5:
        b -= 1
    if b - a < 3 * MIN_SEED or np.isnan(xy[a:b, 0]).sum() > UNSEEN_MAX * (b - a):
        return None
    return a, b


def read_again(video, read: ReadOptions, req, clip, t0: float, plan, *, progress: bool = False):
    """(clip, t0, plan): the clip read again where the observation the plan chose reads it better
    otherwise (light_in_colour, level_in_detail, extent_in_detail); the observation the plan
    chose is kept."""
    clip, t0, plan = light_in_colour(video, read, req, clip, t0, plan, progress=progress)
    clip, t0, plan = level_in_detail(video, read, req, clip, t0, plan, progress=progress)
    return extent_in_detail(video, read, req, clip, t0, plan, progress=progress)


# the short side a level is read at, where the source has it: the default frames' 64 rows leave a
# generated drain's level 4-5 rows of travel, read with slow errors of 0.06 rows (k 2.6% off with
# +-3%); at its source's 135 rows, 10 rows (k 1.3% off with +-2%)
LEVEL_SHORT = 360
# the short side a size or distance is read at in colour, where the source has it, and at most
# this many pixels in all the frames (a long clip is read smaller: memory stays bounded): the
# outline of a ball on the generated falls at 64 rows in colour gives g +1.0% (rms 4.0%), at 128
# -0.1% (rms 1.6%) (train/observe/extent.py)
EXTENT_SHORT = 360
EXTENT_PIXELS = 2e7


def level_in_detail(video, read: ReadOptions, req, clip, t0: float, plan, *, progress: bool = False):
    """(clip, t0, plan): the clip read again at up to LEVEL_SHORT on its short side (the source's
    own size where smaller) where the plan reads a level from shrunk frames: the level is read as
    a fraction of a row, and more rows read it finer. Not where the user gave --size, --roi or a
    mask (the frames are then theirs), nor where the frames read again show no level."""
    from fitode.train.observe.level import LevelObservation, read_level

    if read.roi is not None or read.mask is not None or not _reads(plan, LevelObservation):
        return clip, t0, plan

    def shows(frames) -> bool:
        level = read_level(frames, plan.n_train)
        # more rows can split what the shrunk frames saw as one line (the real bottle at 360 rows)
        return level is not None and level.is_level
    return _finer(video, read, req, clip, t0, plan, short=LEVEL_SHORT, color=read.color, shows=shows,
                  why="the level is read as a fraction of a row", progress=progress)


def extent_in_detail(video, read: ReadOptions, req, clip, t0: float, plan, *, progress: bool = False):
    """(clip, t0, plan): the clip read again in colour at up to EXTENT_SHORT on its short side
    (within EXTENT_PIXELS) where the plan reads a size or a distance: the outline of an object is
    placed by its colour against the background's (train/observe/extent.py), and a radius of
    more pixels is read finer. Not where the user gave --size (the frames are then theirs); the
    region (--roi) and the mask stay theirs."""
    from fitode.train.observe.size import SizeObservation

    if not _reads(plan, SizeObservation):
        return clip, t0, plan
    hs, ws = _region(clip)
    budget = (EXTENT_PIXELS / (max(int(clip.frames.shape[0]), 1) * hs * ws)) ** 0.5
    return _finer(video, read, req, clip, t0, plan, short=EXTENT_SHORT, color=True, shows=None, limit=budget,
                  why="the object's outline is placed by its colour against the background's", progress=progress)


def _region(clip) -> tuple[int, int]:
    """(H, W) of what the read crops from the source: --roi's box, or the whole frame."""
    return (int(clip.roi[3]), int(clip.roi[2])) if clip.roi else tuple(clip.source_size)


def _reads(plan, kind) -> bool:
    return any(isinstance(p, kind) for p in _observation_parts(plan))


def _finer(video, read: ReadOptions, req, clip, t0: float, plan, *, short: int, color: bool, why: str,
           shows=None, limit: float = 1.0, progress: bool = False):
    """(clip, t0, plan): the clip read again at up to `short` on its short side, the source's own
    size where smaller, scaled down further by `limit`, in colour if `color`; re-planned with the
    observation the plan chose, and a note of the clip saying so and `why`. The clip as it was
    where the user gave --size, where that is no finer (and no colour gained), or where
    shows(frames) says the finer frames do not show it."""
    from dataclasses import replace

    from fitode import api

    if read.size is not None:
        return clip, t0, plan
    hs, ws = _region(clip)
    scale = min(1.0, short / min(hs, ws), limit)
    size = (max(1, round(hs * scale)), max(1, round(ws * scale)))
    gains_colour = color and int(clip.frames.shape[1]) < 3
    if size[0] <= int(clip.frames.shape[-2]) and not gains_colour:
        return clip, t0, plan
    size = size if size[0] > int(clip.frames.shape[-2]) else tuple(int(v) for v in clip.frames.shape[-2:])
    finer, t1 = _read_same(video, replace(read, size=size, color=color), req, clip, progress=progress)
    frames = api.as_frames(finer.frames)
    if shows is not None and not shows(frames):
        return clip, t0, plan
    h, w = finer.size
    finer.notes.append(f"read again at {w}x{h}{' in colour' if color and not read.color else ''}: {why}")
    req = replace(req, observe=plan.observation)
    return finer, t1, api.plan(req, frames, finer.dt, track=finer.track, geometry=geometry(finer))


def _observation_parts(plan):
    """The plan's observation models: each state's where states are observed apart, else the one."""
    return getattr(plan.observation, "parts", {"": plan.observation}).values()


def _read_same(video, read: ReadOptions, req, clip, *, progress: bool = False):
    """(clip, t0): the frames of `clip` read again as `read` says (another size, colour), at its
    stride: the stride's reason and the object's track (measured at the source's resolution) are
    the first read's, not read or measured again."""
    from dataclasses import replace

    again, t0 = read_clip(video, replace(read, stride=clip.stride), req.calibration, progress=progress, track=False)
    again.track, again.stride_reason = clip.track, clip.stride_reason
    return again, t0


def light_in_colour(video, read: ReadOptions, req, clip, t0: float, plan, *, progress: bool = False):
    """(clip, t0, plan): the clip read again in colour where the plan reads light decoded from sRGB
    out of gray frames. Gray and the shrinking mix the encoded values, and the sRGB curve does not
    pass through a mix: a red lamp's light decoded from its gray values decays 2.7% slower than
    the mean of its decoded channels (the generated LED). Decoded first, the channels and pixels mix
    as light. The observation the plan chose is kept, its curve too."""
    from dataclasses import replace

    from fitode import api
    from fitode.train.observe.brightness import BrightnessObservation

    if read.color or not any(isinstance(p, BrightnessObservation) and p.light == "srgb"
                             for p in _observation_parts(plan)):
        return clip, t0, plan
    clip, t0 = _read_same(video, replace(read, color=True), req, clip, progress=progress)
    req = replace(req, observe=plan.observation)
    return clip, t0, api.plan(req, api.as_frames(clip.frames), clip.dt, track=clip.track, geometry=geometry(clip))


def source_measurement(result, clip) -> None:
    """The measurement record of a fit on a clip's frames, mapped to the source video's pixels
    (fitode.measurement), in place."""
    from fitode.measurement import geometry, in_source_pixels
    if result.meta.get("measurement") is not None:
        result.meta["measurement"] = in_source_pixels(result.meta["measurement"], geometry(clip))


STILLS = 4  # frames track.png draws on


def plot_track(path: Path, result, clip, video, t0: float) -> Path:
    """track.png: the measurement record on STILLS frames of the source at full resolution (the
    clip's shrunk frames, enlarged, where the source cannot be read again), spread over the
    stretch fitted (the whole clip where none was found)."""
    import numpy as np

    from fitode import plots
    from fitode.measurement import geometry, readings

    n = int(clip.frames.shape[0])
    stretch = result.meta.get("stretch")
    lo, hi = (int(stretch["start_frame"]), int(stretch["end_frame"])) if stretch else (0, n)
    pieces = result.meta.get("pieces") or {}
    if pieces.get("pieces"):  # every piece, and the hold before them
        held = any(e["kind"] in ("hold", "moved") for e in pieces.get("events", ()))
        lo, hi = (0 if held else int(pieces["pieces"][0][0])), int(pieces["pieces"][-1][1])
    lo, hi = max(0, min(lo, n - 1)), max(1, min(hi, n))
    from fitode.video.stills import kept_stills, source_stills
    want = min(STILLS, hi - lo)
    # the frames the read kept at full resolution, where the stretch holds enough of them: no second decode
    have = [i for i in range(lo, hi) if int(clip.frame_indices[i]) in (clip.stills or {})]
    if len(have) >= min(want, 3):
        idx = [have[j] for j in sorted({int(j) for j in np.linspace(0, len(have) - 1, min(want, len(have))).round()})]
    else:
        idx = sorted({int(i) for i in np.linspace(lo, hi - 1, want).round()})
    source = [int(clip.frame_indices[i]) for i in idx]
    h, w = clip.source_size
    got = kept_stills(clip.stills, source)
    if len(got) < len(source):
        try:
            got = source_stills(video, source)
        except Exception:  # noqa: BLE001 - a picture falls back to the frames the fit had
            got = {}
    box = geometry(clip).box
    stills = {}
    for i, s in zip(idx, source):
        if s in got:
            stills[i] = (got[s], (-0.5, w - 0.5, h - 0.5, -0.5))
        else:
            img = np.asarray(clip.frames[i], dtype=float).transpose(1, 2, 0)
            img = np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img
            stills[i] = (np.clip(img, 0, 1), (box[0] - 0.5, box[0] + box[2] - 0.5, box[1] + box[3] - 0.5, box[1] - 0.5))
    m = result.meta.get("measurement")
    maps = ((result.calibration or {}).get("maps") or {})
    return plots.plot_track(path, m, stills, np.asarray(result.time) + t0,
                            readings=readings(m, result.latent, result.rollout, result.states),
                            stretch=stretch, train_frames=result.train_frames,
                            calibrated={s: (v["a"], v["b"]) for s, v in maps.items()},
                            source_frames=[int(f) for f in clip.frame_indices], pieces=pieces or None)


def _slow_motion_hint(result, clip) -> list[str]:
    """Which --fps would make a known constant (g) right, where it came out a slow-motion factor squared off."""
    from fitode.eqparse.parser import KNOWN_CONSTANTS
    from fitode.video.timing import slow_motion_hint
    own = bool(result.meta.get("physical_units"))
    values = {n: e.value for n, e in result.parameters.items() if n in KNOWN_CONSTANTS and (e.calibrated or own)}
    return slow_motion_hint(KNOWN_CONSTANTS, values, float(clip.fps))


def _read(video, **kw):
    from fitode import video as vid
    path = Path(str(video))
    if not path.exists():
        raise FitodeError(f"{video}: no such file or folder")
    for key, parser in (("roi", "parse_roi"), ("size", "parse_size"), ("stride", "parse_stride")):
        if isinstance(kw[key], str):
            kw[key] = getattr(vid, parser)(kw[key])
    return vid.read_video(path, **kw)


class _Recorder:
    """Keeps every step's numbers so an interrupted or failed fit still leaves its history."""

    def __init__(self, names: Iterable[str], chained=None):
        self.names = list(names)
        self.runs: dict[int, dict[str, Any]] = {}
        self.chained = chained

    def __call__(self, info) -> None:
        run = self.runs.setdefault(info.run, {"index": info.run, "status": "running", "final": {},
                                              "history": History.for_constants(self.names)})
        run["history"].append(info.step, info.loss, info.mse, info.kl, info.constants)
        run["final"], run["loss"], run["steps"] = dict(info.constants), info.loss, info.step
        if self.chained is not None:
            self.chained(info)

    def rows(self) -> list[dict[str, Any]]:
        return [{**self.runs[k], "history": self.runs[k]["history"].to_dict()} for k in sorted(self.runs)]


def _write_partial(report: dict, recorder: _Recorder, folder: Path, status: str, why: str,
                   plots_done: list[str], plots: bool, stage: str | None = None) -> None:
    """Whatever a run that did not finish has: the per-step history and the last constants of each
    run, and an estimates.csv with no rows (no estimate was made)."""
    from fitode import plots as plots_module
    from fitode import report as rep
    from fitode.tables import write_run_tables
    rows = recorder.rows()
    if rows and status == "interrupted":
        rows[-1]["status"] = "interrupted"
    for r in rows:
        if r["status"] == "running":
            # the recorder only sees steps; a run that ended before the last one is "ended" (ok or failed
            # is the trainer's to say), and when every run failed they all did
            r["status"] = "failed" if status == "failed" else "ended"
    rep.partial_report(report, rows, status, why)
    if stage is not None:
        report["stage"] = stage
    plots_done += write_run_tables(report, folder)
    if rows:
        if plots:
            _try_plot(plots_module.plot_params, folder / "params.png", rows, {}, plots_done=plots_done)
            _try_plot(plots_module.plot_loss, folder / "loss.png", rows, plots_done=plots_done)
        rep.write_json({"runs": rows}, folder / "history.json")
        plots_done.append("history.json")
    report["files"] = sorted(["result.json", *plots_done])
    rep.write_json(report, folder / "result.json")
