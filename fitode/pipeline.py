"""The single-video job behind `fitode VIDEO --eq ...` (and each item of `fitode batch`).

run_video reads the video, says what it understood, fits, calibrates when asked, and writes
an output folder: result.json (the report), fit.json (the full FitResult with every run's
history, reloadable with FitResult.load), latent.png, params.png, loss.png and frames.png.
An interrupted run (Ctrl-C) or one where every restart failed still leaves a folder, with
result.json marked "incomplete" or "failed" and whatever plots its data allow.
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

from fitode.errors import FitodeError
from fitode.train.history import History  # torch-free, like everything this module imports at the top

DEFAULT_TRAIN_FRACTION = 1.0
RUNS_DIR = "fitode-runs"


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during training, after the folder was written (status "incomplete"); .outcome has it."""

    def __init__(self, outcome: "RunOutcome"):
        super().__init__("interrupted")
        self.outcome = outcome


@dataclass
class RunOutcome:
    """What run_video returns. report is exactly what result.json holds."""

    result: Any  # fitode.train.result.FitResult (not imported here so `import fitode.pipeline` stays light)
    out_dir: Path
    report: dict[str, Any]
    warnings: list[str] = field(default_factory=list)


def run_video(video: str | Path, out_dir: str | Path | None = None, *, eq: str | None = None,
              eq_file: str | None = None, system: str | None = None, const: Mapping[str, float] | None = None,
              free: Iterable[str] = (), init: Mapping[str, float] | None = None,
              prior: tuple[float, float] | None = None, fps: float | None = None, start: float | None = None,
              end: float | None = None, roi=None, size=None, color: bool = False, stride: int | str = "auto",
              mask=None, calibrate: str | None = None, observe: str | None = None,
              train_fraction: float = DEFAULT_TRAIN_FRACTION,
              progress: bool = False, log: Callable[[str], None] | None = print,
              **train_options) -> RunOutcome:
    """Fit one video and write its output folder; see the module docstring.

    out_dir None makes a new folder fitode-runs/<video-stem>-<YYYYmmdd-HHMMSS>[-N] under the
    current directory; a given out_dir must not exist or be empty. log receives the human
    text (what was understood, per-run summaries, calibration, where files went); None
    silences it. train_options are TrainConfig fields (restarts, max_steps, window,
    integrator, encoder, device, seed, ...) plus `callback` (called with every StepInfo).
    Raises FitodeError (one-line message) for any bad input; KeyboardInterrupt propagates after
    the partial folder is written (RunInterrupted, carrying the RunOutcome, when the trainer
    returned what it had).
    """
    from fitode import report as rep

    say = log if log is not None else (lambda _line: None)
    user_callback = train_options.pop("callback", None)

    # Cheap checks first: a typo in an option, the equation or the calibration must not cost a video decode.
    from fitode.api import checked_config
    ode, spec = _resolve_equation(eq, eq_file, system, const, free)
    spec_prior = (spec.prior_mean, spec.prior_std) if spec is not None else (0.0, 1.0)
    config = checked_config(ode, train_options, prior=prior, default_prior=spec_prior, init=init,
                            train_fraction=train_fraction, params=spec.parameters if spec is not None else None)
    use_prior = config.prior
    points = None
    if calibrate is not None:
        from fitode.calibrate import parse_calibration
        points = parse_calibration(calibrate, ode.states)
    target = _check_out_dir(out_dir)
    ident = rep.identifiability(ode)
    analysis = rep.analysis_dict(ident)
    params = dict(spec.parameters) if spec is not None else {}

    clip = _read(video, fps=fps, start=start, end=end, roi=roi, size=size, color=color, stride=stride, mask=mask,
                 progress=progress)
    n_frames = int(clip.frames.shape[0])
    n_train = max(int(round(train_fraction * n_frames)), 1)
    if n_frames == 0:
        raise FitodeError(f"{video}: no frames to fit (check --start/--end)")
    from fitode.train.horizon import resolve_window
    config, window_reason = resolve_window(config, clip.frames[:n_train], clip.dt)
    train_options["window"] = config.window
    if n_train < config.window + 1:
        raise FitodeError(f"{n_train} training frames are fewer than one window of {config.window} frames plus one; "
                          "use a longer clip, a smaller --stride or a smaller --window")
    t0 = float(clip.start_frame) / float(clip.fps)  # video time of frame 0: what --start skipped
    if points is not None:
        from fitode.calibrate import check_times
        check_times(points, t0, t0 + (n_frames - 1) * clip.dt, slack=0.5 * clip.dt)

    from fitode.api import as_frames
    from fitode.train.observe import resolve_observation
    named = spec.observe if observe is None and spec is not None else None
    observation = resolve_observation(observe or named, ode, as_frames(clip.frames[:n_train]), config.light,
                                      config.encoder, source="from the equation file" if named else "as asked")
    settings = {**config.as_dict(), "train_fraction": train_fraction, "observe": observation.name,
                "window_reason": window_reason}
    for line in rep.understanding_lines(ode, spec, analysis, clip, n_train, settings, observation):
        say(line)

    folder = _make_out_dir(target, Path(str(video)).stem)
    recorder = _Recorder(ode.learnable, user_callback)
    options = {"fps": fps, "start": start, "end": end, "roi": roi, "size": size, "color": color, "stride": stride,
               "mask": None if mask is None else str(mask), "calibrate": calibrate}
    report = rep.base_report(video, clip, ode, spec, analysis, settings, n_train, folder, options, t0)
    rep.write_json(report, folder / "result.json")  # "running": even a hard kill leaves a marked folder
    plots_done: list[str] = []
    from fitode import plots
    _try_plot(plots.plot_frames, folder / "frames.png", clip.frames, clip.dt, t0=t0, plots_done=plots_done)

    from fitode.api import fit
    try:
        result = fit(clip.frames, clip.dt, system=ode, params=params, init=init, prior=use_prior,
                     train_fraction=train_fraction, callback=recorder, progress=progress, observe=observation,
                     **train_options)
    except KeyboardInterrupt:
        _write_partial(report, recorder, folder, "incomplete", "interrupted (Ctrl-C) during training", plots_done)
        say(f"interrupted: partial results in {folder}")
        raise
    except FitodeError as exc:
        _write_partial(report, recorder, folder, "failed", str(exc), plots_done)
        raise

    interrupted = bool(result.meta.get("interrupted"))
    for line in rep.run_lines(result):
        say(line)
    calibration = None
    if points is not None and not interrupted:
        from fitode.calibrate import calibrate_result
        calibration = calibrate_result(result, ode, params, points, analysis, time_offset=t0,
                                       seed=int(settings.get("seed", 0)))
        for line in calibration.lines():
            say(line)
        from fitode.train.verdict import rejudge
        result.verdicts = {n: v.to_dict() for n, v in rejudge(
            result, ident, calibrated=calibration.converted_names(), extra=calibration.findings(params)).items()}
    rep.complete_report(report, result, analysis, calibration, t0)
    if interrupted:
        stopped = [r for r in result.runs if r.status == "interrupted"]
        where = f"run {stopped[0].index + 1} at step {stopped[0].steps}" if stopped else "training"
        report["status"] = "incomplete"
        report["error"] = f"interrupted (Ctrl-C) in {where}"
        report["warnings"].append(f"interrupted (Ctrl-C) in {where}: the estimates come from unfinished "
                                  "training" + ("; --calibrate was not applied" if points is not None else ""))
    result.meta.update({"input": report["input"], "calibration": report["calibration"]})
    result.save(folder / "fit.json")
    plot_warnings = _plots_for_result(folder, result, report, calibration, plots_done, t0)
    report["warnings"] += plot_warnings
    report["files"] = sorted(["result.json", "fit.json", *plots_done])
    rep.write_json(report, folder / "result.json")
    say(f"wrote {folder}/ ({', '.join(report['files'])})")
    outcome = RunOutcome(result=result, out_dir=folder, report=report, warnings=list(report["warnings"]))
    if interrupted:
        raise RunInterrupted(outcome)
    return outcome


# ---------------------------------------------------------------------------------------------
def _resolve_equation(eq, eq_file, system, const, free):
    from fitode.eqfile import resolve
    return resolve(eq=eq, eq_file=eq_file, system=system, const=dict(const or {}), free=tuple(free))


def _read(video, **kw):
    from fitode import video as vid
    path = Path(str(video))
    if not path.exists():
        raise FitodeError(f"{video}: no such file or folder")
    for key, parser in (("roi", "parse_roi"), ("size", "parse_size"), ("stride", "parse_stride")):
        if isinstance(kw[key], str):
            kw[key] = getattr(vid, parser)(kw[key])
    return vid.read_video(path, **kw)


def _check_out_dir(out_dir) -> Path | None:
    """A given folder must be absent or empty; checked before any work so a clash costs nothing."""
    if out_dir is None:
        return None
    p = Path(out_dir)
    if p.exists():
        if not p.is_dir():
            raise FitodeError(f"--out {p}: exists and is not a folder")
        if any(p.iterdir()):
            raise FitodeError(f"--out {p}: folder exists and is not empty; fitode never overwrites a run, "
                              "choose another folder")
    return p


def _make_out_dir(target: Path | None, stem: str) -> Path:
    if target is not None:
        target.mkdir(parents=True, exist_ok=True)
        if any(target.iterdir()):  # something appeared while the video was read
            raise FitodeError(f"--out {target}: folder is no longer empty; choose another folder")
        return target
    base = Path(RUNS_DIR)
    base.mkdir(parents=True, exist_ok=True)
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in stem) or "video"
    for n in range(1, 10000):
        p = base / (f"{safe}-{stamp}" if n == 1 else f"{safe}-{stamp}-{n}")
        try:
            p.mkdir()  # atomic: two runs started in the same second get different folders
            return p
        except FileExistsError:
            continue
    raise FitodeError(f"could not make a new folder under {base}")


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


def _try_plot(fn, path: Path, *args, plots_done: list[str], **kw) -> str | None:
    """A plot that cannot be drawn must not lose the numbers: report it as a warning instead."""
    try:
        fn(path, *args, **kw)
    except Exception as exc:  # noqa: BLE001 - matplotlib can fail in many ways; the fit is what matters
        return f"could not draw {path.name}: {type(exc).__name__}: {exc}"
    plots_done.append(path.name)
    return None


def _plots_for_result(folder: Path, result, report, calibration, plots_done: list[str], t0: float) -> list[str]:
    from dataclasses import asdict

    from fitode import plots
    runs = [asdict(r) for r in result.runs]
    for r in runs:
        r["selected"] = r["index"] in result.selected
        r["best"] = r["index"] == result.best
    estimates = {k: v["value"] for k, v in report["parameters"].items()}
    units = {k: v.get("unit") for k, v in report["parameters"].items()}
    latent, rollout, ylabels = result.latent, result.rollout, None
    if calibration is not None:
        latent, rollout, ylabels = calibration.latent, calibration.rollout, calibration.ylabels(result.states)
    warnings = [
        _try_plot(plots.plot_latent, folder / "latent.png", result.time + t0, latent, rollout, result.train_frames,
                  result.states, window=int(result.settings.get("window", 0)) or None, ylabels=ylabels,
                  plots_done=plots_done),
        _try_plot(plots.plot_params, folder / "params.png", runs, estimates, units=units, plots_done=plots_done),
        _try_plot(plots.plot_loss, folder / "loss.png", runs, plots_done=plots_done),
    ]
    return [w for w in warnings if w]


def _write_partial(report: dict, recorder: _Recorder, folder: Path, status: str, why: str,
                   plots_done: list[str]) -> None:
    """Whatever a run that did not finish has: the per-step history and the last constants of each run."""
    from fitode import plots
    from fitode import report as rep
    rows = recorder.rows()
    if rows and status == "incomplete":
        rows[-1]["status"] = "interrupted"
    for r in rows:
        if r["status"] == "running":
            # the recorder only sees steps; a run that ended before the last one is "ended" (ok or failed
            # is the trainer's to say), and when every run failed they all did
            r["status"] = "failed" if status == "failed" else "ended"
    rep.partial_report(report, rows, status, why)
    if rows:
        _try_plot(plots.plot_params, folder / "params.png", rows, {}, plots_done=plots_done)
        _try_plot(plots.plot_loss, folder / "loss.png", rows, plots_done=plots_done)
        rep.write_json({"runs": rows}, folder / "history.json")
        plots_done.append("history.json")
    report["files"] = sorted(["result.json", *plots_done])
    rep.write_json(report, folder / "result.json")
