"""What a run says: the lines printed before training, result.json, and the table at the end.

result.json layout (every run of `fitode VIDEO ...` writes one):
    status            "running" | "complete" | "incomplete" (Ctrl-C) | "failed"
    error             why it is not complete (absent when complete)
    fitode_version, created
    input             file, name, sha256, frames_used, frames_train, frame_shape, fps, fps_source,
                      stride, stride_reason, dt, duration_s, start, end, roi, size, color, mask
    equation          text, normal_form, states, learnable, fixed
    identifiability   per constant: separable, combination, scale, reason (null when unavailable)
    parameters        NAME: value, std, n_runs, unit, scale, latent_units, best_run_only, calibrated, warnings
    calibration       null, or the affine maps and the constants it converted (see fitode.calibrate)
    runs              every restart: index, seed, init, final, loss, steps, status, error, converged,
                      wall_s, selected (histories are in fit.json, or history.json for a partial run)
    selected, best    which runs the estimates average, and the one whose latent is plotted
    settings          every training setting (TrainConfig fields, prior, train_fraction)
    trajectory        time (s), latent and rollout (T x d) of the best run, train_frames;
                      physical units when calibrated
    warnings          every warning the table shows
    files             what the folder holds
"""
from __future__ import annotations

import datetime as _dt
import json
import math
from dataclasses import asdict
from pathlib import Path
from typing import Any, Mapping

from fitode.jsonio import to_jsonable, write_json  # noqa: F401 - write_json: callers use rep.write_json

SPREAD_WARN = 0.05  # restarts "disagree" when their standard deviation exceeds 5% of |value|


# ----------------------------------------------------------------------------- identifiability
def identifiability(ode):
    """The equation's IdentifiabilityReport, or None when the analysis itself fails (it is advice:
    the fit can go on without it)."""
    from fitode.eqparse import analyse
    try:
        return analyse(ode)
    except Exception:  # noqa: BLE001 - sympy can fail in many ways on unusual equations
        return None


def analysis_dict(ident) -> dict[str, Any]:
    """An IdentifiabilityReport as plain data:
    {"constants": {name: {separable, combination, scale, reason}}, "lines": [...]}."""
    if ident is None:
        return {"constants": {}, "lines": ["identifiability analysis failed"]}
    out = {c.name: {"separable": c.separable, "combination": c.combination, "scale": c.scale, "reason": c.reason}
           for c in ident.constants}
    return {"constants": out, "lines": list(ident.lines())}


def _plain(v: Any) -> Any:
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    if isinstance(v, (list, tuple, set, frozenset)):
        return [_plain(x) for x in (sorted(v, key=str) if isinstance(v, (set, frozenset)) else v)]
    return str(v)


def scale_of(analysis: Mapping | None, name: str) -> str | None:
    if not analysis:
        return None
    return (analysis.get("constants", {}).get(name) or {}).get("scale")


def measurable(analysis: Mapping | None, name: str) -> bool:
    """False when the analysis says the constant appears only in a combination with another."""
    if not analysis:
        return True
    item = analysis.get("constants", {}).get(name) or {}
    return item.get("separable", True) is not False


def scale_dependent(analysis: Mapping | None, name: str) -> bool:
    return scale_of(analysis, name) == "dependent"


# ----------------------------------------------------------------------------- before training
def understanding_lines(ode, spec, analysis, clip, n_train: int, settings: Mapping[str, Any],
                        observation=None) -> list[str]:
    """What fitode understood, printed before it spends minutes training."""
    from fitode import __version__
    lines = [f"fitode {__version__}"]
    lines += _clip_lines(clip)
    n = int(clip.frames.shape[0])
    if n_train < n:
        lines.append(f"training frames: the first {n_train} of {n} ({(n_train - 1) * clip.dt:.4g} s); "
                     "the rest shows extrapolation")
    for i, nf in enumerate(ode.normal_form()):
        lines.append(f"{'equation:' if i == 0 else '         '} {nf}")
    units = spec.parameters if spec is not None else {}
    learn = [f"{n}" + (f" [{units[n].unit}]" if n in units and units[n].unit else "") for n in ode.learnable]
    lines.append(f"learnable: {', '.join(learn)}")
    if ode.fixed:
        lines.append("fixed: " + ", ".join(f"{k} = {v:.6g}" for k, v in ode.fixed.items()))
    lines.append(f"prior on the latent: N({settings['prior'][0]:g}, {settings['prior'][1]:g}^2)")
    if (analysis or {}).get("lines"):
        lines.append("identifiability:")
        lines += [f"  {line}" for line in analysis["lines"]]
    if settings.get("gauge", True):
        from fitode.cmd_check import gauge_lines
        lines += gauge_lines(ode)
    from fitode.train.config import TrainConfig, resolve_encoder
    _, encoder = resolve_encoder(TrainConfig(encoder=settings["encoder"]), ode, observation)
    lines.append(f"training: {settings['restarts']} restarts, up to {settings['max_steps']} steps, window "
                 f"{settings['window']} frames, {settings['integrator']} integrator, {settings['device']}, "
                 f"seed {settings['seed']}")
    if settings.get("window_reason"):
        lines.append(f"window: {settings['window_reason']}")
    if observation is not None:
        lines.append(f"observation: {observation.reason}")
        if getattr(observation, "light", None) == "srgb":
            lines.append("light: pixel values decoded from sRGB to linear light (--light linear if they already are)")
    lines.append(f"encoder: {encoder}")
    return lines


def _clip_lines(clip) -> list[str]:
    return list(clip.describe())


# ----------------------------------------------------------------------------- result.json
def base_report(video, clip, ode, spec, analysis, settings: Mapping[str, Any], n_train: int,
                folder: Path, options: Mapping[str, Any] | None = None, t0: float = 0.0) -> dict[str, Any]:
    """result.json before training (status "running"): input, equation, analysis, settings.

    options: the video flags as given (fps, start, end, roi, size, color, stride, mask, calibrate).
    t0: video time of the first frame used.
    """
    from fitode import __version__
    n = int(clip.frames.shape[0])
    units = {k: p.unit for k, p in (spec.parameters.items() if spec is not None else [])}
    return {
        "status": "running",
        "fitode_version": __version__,
        "created": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        "out_dir": str(folder),
        "input": {
            "file": str(video),
            "name": Path(str(video)).name,
            "sha256": clip.sha256,
            "frames_used": n,
            "frames_train": n_train,
            "frame_shape": [int(s) for s in clip.frames.shape[1:]],
            "fps": float(clip.fps),
            "fps_source": clip.fps_source,
            "stride": int(clip.stride),
            "stride_reason": clip.stride_reason,
            "dt": float(clip.dt),
            "duration_s": (n - 1) * float(clip.dt),
            "first_frame_time_s": t0,
            "fps_container": clip.fps_container,
            "source_size": _plain(clip.source_size),
            "n_source_frames": clip.n_source_frames,
            "notes": list(clip.notes),
            "options": {k: _plain(v) for k, v in (options or {}).items()},
        },
        "equation": {
            "text": ode.text,
            "normal_form": ode.normal_form(),
            "states": list(ode.states),
            "learnable": list(ode.learnable),
            "fixed": dict(ode.fixed),
            "units": units,
        },
        "identifiability": analysis,
        "parameters": {},
        "calibration": None,
        "runs": [],
        "selected": [],
        "best": None,
        "settings": _plain_settings(settings),
        "trajectory": None,
        "warnings": [],
        "files": [],
    }


def _plain_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in settings.items() if _jsonable(v)}


def _jsonable(v: Any) -> bool:
    try:
        json.dumps(v)
        return True
    except (TypeError, ValueError):
        return False


def complete_report(report: dict[str, Any], result, analysis, calibration, t0: float = 0.0) -> None:
    """Fill the estimates, runs and trajectory of a finished fit (and its calibration) into report."""
    units = report["equation"].get("units", {})
    n_runs = len(result.runs)
    failed = [r.index for r in result.runs if r.status != "ok"]
    params: dict[str, Any] = {}
    warnings: list[str] = []
    for name, est in result.parameters.items():
        value, std = est.value, est.std
        conv = calibration.constants.get(name) if calibration is not None else None
        if conv is not None and conv["converted"]:
            value, std = conv["after"], conv["std_after"]
        unit = est.unit or units.get(name)
        entry = {"value": value, "std": std, "n_runs": est.n_runs, "unit": unit,
                 "scale": scale_of(analysis, name), "measurable": measurable(analysis, name),
                 "calibrated": bool(conv and conv["converted"]), "latent_units": False,
                 "best_run_only": name in result.meta.get("own_units", ()), "warnings": [],
                 **_verdict(result, name)}
        if scale_dependent(analysis, name) and not entry["calibrated"]:
            entry["latent_units"] = True
            entry["warnings"].append("in latent units: it depends on the latent's arbitrary scale; "
                                     "give --calibrate with known values of the state for physical units")
        if not entry["measurable"]:
            item = analysis["constants"].get(name, {})
            comb = item.get("combination")
            entry["warnings"].append("not measurable alone" + (f": the video fixes only {comb}" if comb else ""))
        if scale_of(analysis, name) == "free-small-amplitude" and not entry["calibrated"] and not _gauge_scaled(result):
            entry["warnings"].append("scale-free only for small amplitudes: with large swings the latent's "
                                     "arbitrary scale biases it; calibrate the state to be sure")
        if est.n_runs > 1 and abs(std) > SPREAD_WARN * abs(value):
            rel = abs(std) / abs(value) if value else math.inf
            entry["warnings"].append(f"restarts disagree: spread {_pct(rel)} of the value")
        params[name] = entry
        warnings += [f"{name}: {w}" for w in entry["warnings"]]
    if failed:
        warnings.append(f"{len(failed)} of {n_runs} restarts failed (runs {', '.join(str(i + 1) for i in failed)})")
    dropped = [r.index for r in result.runs if r.status == "ok" and r.index not in result.selected]
    if dropped:
        warnings.append(f"{len(dropped)} of {n_runs} restarts ended with a loss more than "
                        f"{result.selection_factor:g}x the best and were left out of the estimate "
                        f"(runs {', '.join(str(i + 1) for i in dropped)})")
        elsewhere = [r for r in result.runs if r.index in dropped and any(
            abs(r.value(n) - e.value) > SPREAD_WARN * max(abs(e.value), 1e-12) for n, e in result.parameters.items())]
        # a measured latent is the same for every restart: a restart left out fitted it worse
        if elsewhere and not result.meta.get("geometric"):
            ends = "; ".join(f"run {r.index + 1}: " + ", ".join(f"{n}={r.value(n):.4g}" for n in r.final)
                             for r in elsewhere)
            # measured on the paper's scale video: an overdamped fit (g1 ~ 14) reached a lower loss
            # than the true basin, so the lowest loss alone does not settle which basin is right
            warnings.append(f"restarts left out ended elsewhere ({ends}): the loss may prefer a wrong basin; "
                            "compare latent.png and params.png, or rerun with more --restarts")
    not_converged = [r.index for r in result.runs if r.status == "ok" and not r.converged]
    if not_converged and len(not_converged) == len([r for r in result.runs if r.status == "ok"]):
        warnings.append("no restart settled before --max-steps; the estimates may still be moving "
                        "(see params.png; raise --max-steps)")
    report["parameters"] = params
    report["runs"] = [_run_entry(asdict(r), r.index in result.selected) for r in result.runs]
    report["selected"] = list(result.selected)
    report["best"] = int(result.best)
    report["checks"] = to_jsonable(result.checks)
    latent, rollout = result.latent, result.rollout
    if calibration is not None:
        latent, rollout = calibration.latent, calibration.rollout
    report["trajectory"] = {
        "time": [float(t) + t0 for t in result.time],
        "train_frames": int(result.train_frames),
        "states": list(result.states),
        "units": "physical" if calibration is not None else "latent",
        "latent": to_jsonable(latent),
        "rollout": to_jsonable(rollout),
    }
    report["calibration"] = calibration.to_dict() if calibration is not None else None
    report["warnings"] = warnings + report.get("warnings", [])
    report["status"] = "complete"
    report.pop("error", None)


def _gauge_scaled(result) -> bool:
    """True when the best run learned the scale between latent and state (fitode.eqparse.gauge),
    so a large swing no longer biases an amplitude-dependent constant."""
    gauge = result.runs[result.best].gauge if result.runs else {}
    return any(abs(g.get("scale", 1.0) - 1.0) > 1e-9 for g in gauge.values())


def _verdict(result, name: str) -> dict[str, str]:
    v = result.verdicts.get(name) or {"verdict": "not trustworthy", "reason": "no verdict was made"}
    return {"verdict": v["verdict"], "verdict_reason": v["reason"], "verdict_other_reasons": v.get("other_reasons", [])}


def _run_entry(run: dict[str, Any], selected: bool) -> dict[str, Any]:
    keep = ("index", "seed", "init", "final", "loss", "steps", "status", "error", "converged", "wall_s",
            "score", "stop_reason", "gauge")
    out = {k: run.get(k) for k in keep}
    out["selected"] = selected
    return out


def partial_report(report: dict[str, Any], rows: list[dict[str, Any]], status: str, why: str) -> None:
    """A fit that did not finish: the last numbers of each run, no estimates."""
    report["status"] = status
    report["error"] = why
    report["runs"] = [{"index": r["index"], "final": r.get("final", {}), "loss": r.get("loss"),
                       "steps": r.get("steps", 0), "status": r.get("status")} for r in rows]
    report["parameters"] = {}
    report["warnings"] = report.get("warnings", []) + [f"run {status}: {why}; no estimates were made"]


# ----------------------------------------------------------------------------- after training
def run_lines(result) -> list[str]:
    """One line per restart: how it ended."""
    lines = []
    for r in result.runs:
        mark = "*" if r.index == result.best else ("+" if r.index in result.selected else " ")
        consts = " ".join(f"{k}={v:.5g}" for k, v in r.final.items())
        state = "settled" if r.converged else ("failed: " + (r.error or "?") if r.status != "ok" else "step limit")
        score = f"score {r.score:5.2f}" if r.score is not None else "score   -  "
        lines.append(f"run {r.index + 1:>2}{mark} {r.steps:>5} steps  loss {r.loss:.4g}  {score}  "
                     f"{consts}  ({state})")
    if result.meta.get("subspace"):
        lines.insert(0, result.meta["subspace"])
    wall = max((r.wall_s for r in result.runs), default=0.0)
    lines.append(f"           (* best run, + also averaged into the estimate; {len(result.runs)} restarts "
                 f"trained together in {wall:.1f} s; score: does the latent tell the frames apart, 1 = fully)")
    return lines


def format_table(report: Mapping[str, Any]) -> str:
    """The table printed at the end: name, value, spread over restarts, unit, then the warnings."""
    params = report.get("parameters") or {}
    out = []
    if not params:
        out.append(f"no estimates: run {report.get('status')} ({report.get('error', '')})")
    elif report.get("status") != "complete":
        out.append(f"run {report.get('status')}: {report.get('error', '')}")
    if params:
        n_runs = len(report.get("runs", []))
        n_sel = len(report.get("selected", []))
        rows = [("constant", "value", "spread", "unit", "verdict")]
        for name, p in params.items():
            # a value in the latent's arbitrary units has none of the equation file's physical unit
            unit = "latent units" if p.get("latent_units") else p.get("unit") or ""
            spread = f"±{_spread(p['std'])}" if p.get("n_runs", 1) > 1 else "-"
            rows.append((name, _num(p["value"]), spread, unit, p.get("verdict", "")))
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        out.append(f"estimates (mean over {n_sel} of {n_runs} restarts; spread = their standard deviation)")
        only = [n for n, p in params.items() if p.get("best_run_only")]
        if only and n_sel > 1:
            out.append(f"  ({', '.join(only)}: the best restart's alone; each restart reads the same measured path "
                       "in units of its own)")
        for i, r in enumerate(rows):
            out.append("  " + "  ".join([r[0].ljust(widths[0]), r[1].rjust(widths[1]), r[2].rjust(widths[2]),
                                         r[3].ljust(widths[3]), r[4].upper() if i else r[4]]).rstrip())
        for name, p in params.items():
            if p.get("verdict_reason"):
                out.append(f"  {name}: {p['verdict']}: {p['verdict_reason']}")
    cal = report.get("calibration")
    if cal:
        out.append("calibration: " + "; ".join(f"{s} = {m['a']:.6g}*latent + {m['b']:.6g}"
                                               for s, m in cal["maps"].items()))
    warnings = report.get("warnings") or []
    for w in warnings:
        out.append(f"warning: {w}")
    return "\n".join(out)


def _num(v: float | None) -> str:
    if v is None or not math.isfinite(v):
        return "nan"
    if v == 0:
        return "0"
    mag = abs(v)
    if 1e-3 <= mag < 1e5:
        decimals = max(0, 4 - int(math.floor(math.log10(mag))))
        return f"{v:.{min(decimals, 7)}f}"
    return f"{v:.4e}"


def _spread(v: float | None) -> str:
    """Two significant digits: a spread is itself uncertain."""
    if v is None or not math.isfinite(v):
        return "nan"
    return f"{v:.2g}"


def _pct(rel: float) -> str:
    return f"{100 * rel:.0f}%" if rel >= 0.1 else f"{100 * rel:.1f}%"
