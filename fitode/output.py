"""The output folder of a run and the pictures of a result: checked before any work (a clash or an
unwritable place costs no decode), made when the fit starts, drawn without losing the numbers
when a plot fails. Read by the command line's run (pipeline.py) and by Result.save (result.py)."""
from __future__ import annotations

import datetime as _dt
from pathlib import Path

from fitode.errors import FitodeError

RUNS_DIR = "fitode-runs"


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
    check_writable(p)
    return p


def check_writable(p: Path) -> None:
    """A folder can be made at p and written in: tried now (made and removed again), so an
    unwritable place (/proc/x, a path through a file) costs no decode and no fit."""
    made = [a for a in (p, *p.parents) if not a.exists()]
    probe = p / ".fitode-write-check"
    try:
        p.mkdir(parents=True, exist_ok=True)
        probe.touch()
        probe.unlink()
    except OSError as exc:
        above = next((a for a in p.parents if a.exists()), None)
        why = (f"{above} is a file, not a folder" if above is not None and not above.is_dir()
               else exc.strerror or type(exc).__name__)
        raise FitodeError(f"--out {p}: cannot write there ({why}); choose another folder") from None
    finally:
        for a in made:  # nothing is left behind until the fit writes its folder
            try:
                a.rmdir()
            except OSError:
                break


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


def _try_plot(fn, path: Path, *args, plots_done: list[str], **kw) -> str | None:
    """A plot that cannot be drawn must not lose the numbers: report it as a warning instead."""
    try:
        fn(path, *args, **kw)
    except Exception as exc:  # noqa: BLE001 - matplotlib can fail in many ways; the fit is what matters
        return f"could not draw {path.name}: {type(exc).__name__}: {exc}"
    plots_done.append(path.name)
    return None


def _plots_for_result(folder: Path, result, report, plots_done: list[str], t0: float) -> list[str]:
    from dataclasses import asdict

    import numpy as np

    from fitode import plots
    latent, rollout, ylabels = result.latent, result.rollout, plots.state_labels(result)
    if result.calibration is not None:
        latent, rollout = np.asarray(result.calibration["latent"]), np.asarray(result.calibration["rollout"])
        ylabels = result.calibration["ylabels"]
    measured = bool(result.meta.get("direct"))
    warnings = [
        _try_plot(plots.plot_latent, folder / "latent.png", result.time + t0, latent, rollout, result.train_frames,
                  result.states, window=int(result.settings.get("window", 0)) or None, ylabels=ylabels,
                  angles=plots.angle_states(result), measured=measured, plots_done=plots_done),
    ]
    if not measured:  # a path fitted directly has no training: its "history" is a solver's two end points
        runs = [asdict(r) for r in result.runs]
        for r in runs:
            r["selected"] = r["index"] in result.selected
            r["best"] = r["index"] == result.best
        estimates = {k: v["value"] for k, v in report["parameters"].items()}
        units = {k: v.get("unit") for k, v in report["parameters"].items()}
        shown = plots.params_view(result, report["parameters"])
        warnings += [_try_plot(plots.plot_params, folder / "params.png", runs, estimates, units=units, **shown,
                               plots_done=plots_done),
                     _try_plot(plots.plot_loss, folder / "loss.png", runs, plots_done=plots_done)]
    return [w for w in warnings if w]
