"""What a run says: the lines printed before training, result.json, and the table at the end.

result.json layout (every run of `fitode VIDEO ...` writes one):
    status            "running" | "complete" | "interrupted" (Ctrl-C, SIGTERM) | "failed"
    stage             where an interrupted run stopped: training, calibration, intervals, assessment,
                      pictures (fitode.interrupted; the estimates are kept wherever training finished)
    error             why it is not complete (absent when complete)
    fitode_version, created
    input             file, name, sha256, frames_used, frames_train, frame_shape, fps, fps_source,
                      stride, stride_reason, dt, duration_s, start, end, roi, size, color, mask
    equation          text, normal_form, states, learnable, fixed
    identifiability   per constant: separable, combination, scale, reason (null when unavailable)
    parameters        NAME: value, std, n_runs, unit, scale, latent_units, best_run_only, calibrated,
                      calibrated_path (the value is one fit of the path as calibrated, its zero set by
                      the calibration: no mean over restarts), latent_value (before calibration),
                      verdict, verdict_reason, verdict_other_reasons
    calibration       null, or the affine maps and the constants it converted (see fitode.calibrate)
    runs              every restart: index, seed, init, final, loss, steps, status, error, converged,
                      wall_s, selected (histories are in fit.json, or history.json for a partial run)
    selected, best    which runs the estimates average, and the one whose latent is plotted
    settings          every training setting (TrainConfig fields, prior, train_fraction)
    trajectory        time (s), frames (the source video's frame numbers, as track.csv and track.png
                      give them), latent and rollout (T x d) of the best run, train_frames;
                      physical units when calibrated
    plan              the choices of the fit (observation, encoder, window): value and reason each
    checks            the numbers behind the verdicts and every finding (fitode.train.assess)
    warnings          findings that are no verdict's headline reason, and what went wrong around the fit
    notes             what happened to the restarts (left out, failed) and why, no judgement
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
def understanding_lines(ode, spec, analysis, clip, plan) -> list[str]:
    """What fitode understood, printed before it spends minutes training: the clip, the equation,
    what the video can measure, and the plan's choices with their reasons."""
    from fitode._version import __version__
    lines = [f"fitode {__version__}"]
    lines += _clip_lines(clip)
    n = int(clip.frames.shape[0])
    if plan.n_train < n:
        lines.append(f"training frames: the first {plan.n_train} of {n} ({(plan.n_train - 1) * clip.dt:.4g} s); "
                     "the rest shows extrapolation")
    for i, nf in enumerate(ode.normal_form()):
        lines.append(f"{'equation:' if i == 0 else '         '} {nf}")
    units = spec.parameters if spec is not None else {}
    learn = [f"{n}" + (f" [{units[n].unit}]" if n in units and units[n].unit else "") for n in ode.learnable]
    lines.append(f"learnable: {', '.join(learn)}")
    from fitode.describe import hint_lines
    lines += hint_lines(ode)
    if ode.fixed:
        lines.append("fixed: " + ", ".join(f"{k} = {v:.6g}" for k, v in ode.fixed.items()))
    lines.append(f"prior on the latent: N({plan.prior[0]:g}, {plan.prior[1]:g}^2)")
    if (analysis or {}).get("lines"):
        lines.append("identifiability:")
        lines += [f"  {line}" for line in analysis["lines"]]
    if plan.config.gauge:
        from fitode.describe import gauge_lines
        lines += gauge_lines(ode, plan.observation)
    return lines + plan.lines() + length_lines(plan.observation)


def length_lines(observation) -> list[str]:
    """How a measured length reads: source pixels (y up), or metres through a scale stick."""
    lengths = observation.lengths
    if not observation.reads_lengths:
        if lengths.metres_per_px:
            return [f"lengths: --scale is not used: the {observation.name} observation reads no length on the frames "
                    "(--observe position measures the state in metres)"]
        return []
    if lengths.metres_per_px:
        return [f"lengths: in metres (x right, y up), {1000 * lengths.metres_per_px:.5g} mm per source pixel "
                f"from --scale (±{100 * lengths.relative_std:.2g}%)"]
    return ["lengths: in source pixels (x right, y up), constants in units of px and s; --scale gives metres"]


def _clip_lines(clip) -> list[str]:
    return list(clip.describe())


# ----------------------------------------------------------------------------- result.json
def base_report(video, clip, ode, spec, analysis, plan, train_fraction: float, folder: Path,
                options: Mapping[str, Any] | None = None, t0: float = 0.0) -> dict[str, Any]:
    """result.json before training (status "running"): input, equation, analysis, the plan's
    choices with their reasons, settings.

    options: the video flags as given (fps, start, end, roi, size, color, stride, mask, calibrate).
    t0: video time of the first frame used.
    """
    from fitode._version import __version__
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
            "frames_train": plan.n_train,
            "frame_shape": [int(s) for s in clip.frames.shape[1:]],
            "fps": float(clip.fps),
            "fps_source": clip.fps_source,
            "stride": int(clip.stride),
            "stride_reason": clip.stride_reason,
            "dt": float(clip.dt),
            "duration_s": (n - 1) * float(clip.dt),
            "first_frame_time_s": t0,
            "fps_container": clip.fps_container,
            "timing": list(clip.timing),  # what the frames' timestamps changed (fitode.video.timing)
            "capture_fps": clip.capture_fps,  # a slow-motion clip's recorded rate, from its metadata
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
        "plan": plan.to_dict(),
        "settings": _plain_settings({**plan.config.as_dict(), "train_fraction": train_fraction}),
        "trajectory": None,
        "warnings": [],
        "notes": [],
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


def complete_report(report: dict[str, Any], result, analysis, t0: float = 0.0) -> None:
    """Fill the estimates, runs, trajectory, calibration and the assessment's verdicts and warnings
    of a finished fit into report. It only formats: every judgement is the assessment's."""
    units = report["equation"].get("units", {})
    if "settings" in report:  # what the fit resolved after the plan: the integrator's steps per frame
        report["settings"] = _plain_settings({**report["settings"], **result.settings})
    params: dict[str, Any] = {}
    for name, est in result.parameters.items():
        params[name] = {"value": est.value, "std": est.std, "n_runs": est.n_runs, "unit": est.unit or units.get(name),
                        "scale": scale_of(analysis, name), "measurable": measurable(analysis, name),
                        "calibrated": est.calibrated, "latent_value": est.latent_value, "interval": est.interval,
                        "latent_units": scale_dependent(analysis, name) and not est.calibrated
                        and not result.meta.get("physical_units", False),
                        "best_run_only": name in result.meta.get("own_units", ()),
                        "calibrated_path": name in ((result.calibration or {}).get("gauge_fixed") or ()),
                        **_verdict(result, name)}
    report["parameters"] = params
    report["runs"] = [_run_entry(asdict(r), r.index in result.selected) for r in result.runs]
    report["selected"] = list(result.selected)
    report["best"] = int(result.best)
    report["checks"] = to_jsonable(result.checks)
    latent, rollout = result.latent, result.rollout
    if result.calibration is not None:
        latent, rollout = result.calibration["latent"], result.calibration["rollout"]
    report["trajectory"] = {
        "time": [float(t) + t0 for t in result.time],
        "train_frames": int(result.train_frames),
        "states": list(result.states),
        "units": "physical" if result.calibration is not None else "latent",
        # each state's unit where it was measured in one (px, or m with --scale), and not calibrated
        "state_units": {} if result.calibration is not None else dict(result.meta.get("units") or {}),
        "latent": to_jsonable(latent),
        "rollout": to_jsonable(rollout),
    }
    report["calibration"] = ({k: v for k, v in result.calibration.items() if k not in ("latent", "rollout", "lines")}
                             if result.calibration is not None else None)
    report["measurement"] = to_jsonable(result.meta.get("measurement"))
    report["warnings"] = list(result.warnings) + report.get("warnings", [])
    report["notes"] = list(result.notes)
    report["status"] = "complete"
    report.pop("error", None)


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
        # a path fitted directly has its solver's own iterations, not training steps to a limit
        limit = "not settled" if result.meta.get("direct") else "step limit"
        state = ("settled" if r.converged else limit if r.status == "ok" else
                 r.error or r.status if r.status == "interrupted" else "failed: " + (r.error or "?"))
        score = f"score {r.score:5.2f}" if r.score is not None else "score   -  "
        lines.append(f"run {r.index + 1:>2}{mark} {r.steps:>5} steps  loss {r.loss:.4g}  {score}  "
                     f"{consts}  ({state})")
    if result.meta.get("subspace"):
        lines.insert(0, result.meta["subspace"])
    if result.meta.get("stretch"):
        lines.insert(1 if result.meta.get("subspace") else 0, stretch_line(result.meta["stretch"], len(result.time),
                                                                          result.meta.get("input", {}).get("t0", 0.0)))
    if result.meta.get("pieces"):
        lines.insert(2 if result.meta.get("subspace") else 1, pieces_line(result.meta["pieces"], result.dt,
                                                                          result.meta.get("input", {}).get("t0", 0.0)))
    steps = result.checks.get("integrator") or {}
    if int(steps.get("substeps", 1)) > 1 or not steps.get("settled", True):
        lines.insert(len(lines) - len(result.runs), f"integrator: {steps['reason']}")
    wall = max((r.wall_s for r in result.runs), default=0.0)
    how = "fitted directly to the measured path" if result.meta.get("direct") else "trained together"
    lines.append(f"           (* best run, + also averaged into the estimate; {len(result.runs)} restarts "
                 f"{how} in {wall:.1f} s; score: does the latent tell the frames apart, 1 = fully)")
    return lines


def stretch_line(stretch: Mapping[str, Any], n_frames: int, t0: float = 0.0) -> str:
    """The stretch fitted (contract: meta["stretch"]) and what was cut, in one line."""
    a, b = int(stretch["start_frame"]), int(stretch["end_frame"])
    cut = [f"frames 0-{a - 1} before it" if a > 0 else "", f"frames {b}-{n_frames - 1} after it" if b < n_frames else ""]
    cut = " and ".join(c for c in cut if c)
    where = (f"stretch: frames {a}-{b - 1} ({t0 + stretch['start_s']:.3f} s to {t0 + stretch['end_s']:.3f} s of "
             f"the clip), {stretch['source']}: {stretch['reason']}")
    return where + (f"; cut {cut}" if cut else "; nothing cut")


def pieces_line(pieces: Mapping[str, Any], dt: float, t0: float = 0.0) -> str:
    """The pieces found (contract: meta["pieces"], fitode.train.pieces) and their events, and the
    shared fit, in one line."""
    from fitode.train.pieces import Pieces

    line = "pieces: " + Pieces.from_dict(pieces).describe(dt, t0, pieces.get("n_frames"))
    joint = pieces.get("joint")
    if joint:
        line += "; the constants fitted to all " + str(len(pieces["pieces"])) + " together: " + ", ".join(
            f"{n} {v:.5g} +- {joint['errors'][n]:.2g}" for n, v in joint["values"].items())
    return line


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
        rows = [("constant", "value", "95%", "unit", "verdict")]
        for name, p in params.items():
            # a value in the latent's arbitrary units has none of the equation file's physical unit
            unit = "latent units" if p.get("latent_units") else p.get("unit") or ""
            rows.append((name, _num(p["value"]), _interval(p), unit, p.get("verdict", "")))
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        out.append(f"estimates (mean over {n_sel} of {n_runs} restarts; 95% = the half width of the interval "
                   "that holds the truth 95 times in 100: residuals, frame timing, calibration, restarts)")
        only = [n for n, p in params.items() if p.get("best_run_only")]
        if only and n_sel > 1:
            out.append(f"  ({', '.join(only)}: the best restart's alone; each restart reads the same measured path "
                       "in units of its own)")
        refitted = [n for n, p in params.items() if p.get("calibrated_path")]
        if refitted and n_sel > 1:
            out.append(f"  ({', '.join(refitted)}: one fit of the measured path as calibrated; the restarts differ only "
                       "in the zero the calibration sets)")
        for i, r in enumerate(rows):
            out.append("  " + "  ".join([r[0].ljust(widths[0]), r[1].rjust(widths[1]), r[2].rjust(widths[2]),
                                         r[3].ljust(widths[3]), r[4].upper() if i else r[4]]).rstrip())
        for name, p in params.items():
            if p.get("verdict_reason"):
                out.append(f"  {name}: {p['verdict']}: {p['verdict_reason']}")
    if report.get("comparison"):
        out += comparison_lines(report["comparison"])
    cal = report.get("calibration")
    if cal:
        out.append("calibration: " + "; ".join(f"{s} = {m['a']:.6g}*latent + {m['b']:.6g}"
                                               for s, m in cal["maps"].items()))
    out += [f"warning: {w}" for w in report.get("warnings") or []]
    out += [f"note: {n}" for n in report.get("notes") or []]
    return "\n".join(out)


def comparison_lines(comparison: Mapping[str, Any]) -> list[str]:
    """The candidates of a comparison (result.json's `comparison` block): each equation as typed,
    its constants with the half width of their 95% intervals, its held-out error and verdict;
    then the preferred equation, or that the clip cannot tell."""
    rows = [("equation", "constants (95%)", "held-out", "verdict")]
    for c in comparison["candidates"]:
        consts = ", ".join(f"{n} {_num(p['value'])} {_interval(p)}" for n, p in c["parameters"].items()) or "-"
        err = c.get("heldout_error")
        rows.append((c["equation"], consts, "-" if err is None else f"{err:.4g}", c["verdict"]))
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    out = [f"comparison ({comparison['method']}):"]
    out += ["  " + "  ".join([r[0].ljust(widths[0]), r[1].ljust(widths[1]), r[2].rjust(widths[2]), r[3]]).rstrip()
            for r in rows]
    out += [f"  failed: {c['equation']}: {c['error']}" for c in comparison["candidates"] if c.get("error")]
    out += [f"  note: {n}" for n in comparison.get("notes", [])]
    if comparison["preferred"] is not None:
        out.append(f"preferred: {comparison['preferred']} ({comparison['reason']})")
    else:
        out.append(f"preferred: none: {comparison['reason']}; the estimates above are the first candidate's")
    return out


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


def _interval(p: Mapping[str, Any]) -> str:
    """± the half width of the 95% interval (its larger side), two significant digits; "-" for none."""
    iv, v = p.get("interval"), p.get("value")
    if not iv or v is None or not all(isinstance(e, (int, float)) and math.isfinite(e) for e in iv):
        return "-"
    return f"±{_spread(max(v - iv[0], iv[1] - v))}"


def _spread(v: float | None) -> str:
    """Two significant digits: a spread is itself uncertain."""
    if v is None or not math.isfinite(v):
        return "nan"
    return f"{v:.2g}"

