"""What `fitode.fit` returns: a FitResult (fitode.train.result) with the verbs a notebook wants.

    print(result)                       the estimates table the command line prints
    result.summary()                    the same table, as text
    result.confidence_interval("L")     (low, high), 95% or another level
    result.to_dataframe()               one row per constant (pandas, imported only here)
    result.plot()                       the measured (or learned) state and the equation's fit, one figure
    result.save("folder")               result.json, fit.json, estimates.csv, track.csv and the plots
    Result.load("folder")               back from a saved folder (or its fit.json)

In Jupyter a result shows itself as an HTML table (_repr_html_). The table, the CSV files and
result.json are made by the same code as `fitode VIDEO`'s (fitode.report, fitode.tables), so
the numbers and words are the same. This module only formats: every number and verdict is the
fit's and the assessment's.
"""
from __future__ import annotations

import html
import math
from dataclasses import fields
from pathlib import Path
from typing import Any

from fitode.errors import ConfigError
from fitode.train.result import FitResult

Z95 = 1.959963984540054  # the normal quantile of a two-sided 95% interval


class Result(FitResult):
    """A FitResult (every field documented there) with summary, confidence_interval,
    to_dataframe, plot, save and load, and a table for print() and Jupyter."""

    @classmethod
    def of(cls, result: FitResult) -> "Result":
        """The same fit as a Result (its fields shared, not copied)."""
        if isinstance(result, cls):
            return result
        return cls(**{f.name: getattr(result, f.name) for f in fields(FitResult)})

    # ------------------------------------------------------------------ reading it
    def report(self) -> dict[str, Any]:
        """What result.json holds for this fit (fitode.report's layout), made from the result alone:
        the input's facts where the fit read a video path, else the frames' time step."""
        return report_of(self)

    def summary(self) -> str:
        """The table `fitode VIDEO` prints at the end: each constant's value, the half width of its
        95% interval, its unit and verdict, each verdict's reason, then the warnings and notes."""
        from fitode.report import format_table
        return format_table(self.report())

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        est = ", ".join(f"{n}={e.value:.6g}" for n, e in self.parameters.items())
        verdicts = ", ".join(f"{n}: {v.get('verdict')}" for n, v in self.verdicts.items())
        return f"<fitode Result {self.equation!r}: {est}; {verdicts or 'no verdicts'}>"

    def _repr_html_(self) -> str:
        rep = self.report()
        from fitode.report import _interval, _num
        head = "".join(f"<th>{h}</th>" for h in ("constant", "value", "95%", "unit", "verdict", "reason"))
        rows = []
        for name, p in (rep.get("parameters") or {}).items():
            unit = "latent units" if p.get("latent_units") else p.get("unit") or ""
            cells = (name, _num(p["value"]), _interval(p), unit, (p.get("verdict") or "").upper(),
                     p.get("verdict_reason") or "")
            rows.append("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in cells) + "</tr>")
        status = rep.get("status")
        top = f"<p><b>{html.escape(self.equation)}</b>" + (
            f" &mdash; {html.escape(status)}: {html.escape(str(rep.get('error', '')))}" if status != "complete" else "")
        notes = "".join(f"<li>warning: {html.escape(w)}</li>" for w in rep.get("warnings") or [])
        notes += "".join(f"<li>note: {html.escape(n)}</li>" for n in rep.get("notes") or [])
        return (f"{top}</p><table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"
                + (f"<ul>{notes}</ul>" if notes else ""))

    def confidence_interval(self, name: str, level: float = 0.95) -> tuple[float, float]:
        """(low, high) of constant `name` at `level`: the fit's 95% interval (fitode.train.interval),
        each side scaled by the normal quantiles z(level) / z(0.95) for another level. ValueError
        where the fit made none (an interrupted run, a constant the clip cannot pin)."""
        if name not in self.parameters:
            raise ConfigError(f"no constant {name!r}; the constants are {', '.join(self.parameters)}")
        if isinstance(level, bool) or not isinstance(level, (int, float)) or not 0 < level < 1:
            raise ConfigError(f"level must be a probability in (0, 1), got {level!r}")
        est = self.parameters[name]
        iv = est.interval
        if not iv or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in iv):
            why = (self.verdicts.get(name) or {}).get("reason", "none was made")
            raise ValueError(f"{name} has no interval: {why}")
        from statistics import NormalDist
        k = NormalDist().inv_cdf(0.5 + level / 2) / Z95
        return (est.value - k * (est.value - iv[0]), est.value + k * (iv[1] - est.value))

    def to_dataframe(self):
        """One row per constant, indexed by name: the columns of estimates.csv (value, interval_low,
        interval_high, restart_spread, unit, calibrated, verdict, reason). Needs pandas, which
        fitode does not depend on."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_dataframe needs pandas, which is not installed (pip install pandas); "
                              "result.report()['parameters'] has the same numbers as plain data") from None
        from fitode.jsonio import to_jsonable
        from fitode.tables import ESTIMATE_COLUMNS, estimate_rows
        rows = estimate_rows(to_jsonable(self.report())["parameters"])
        return pd.DataFrame(rows, columns=list(ESTIMATE_COLUMNS)).set_index("constant")

    def plot(self, path: str | Path | None = None):
        """The measured or learned state (dots) and the equation's trajectory with the estimates
        (line) against video time, one panel per state, in physical units where calibrated or
        measured so (latent.png's figure). Returns the matplotlib Figure; with path, also saved there."""
        from fitode import plots
        latent, rollout, ylabels = self.latent, self.rollout, plots.state_labels(self)
        if self.calibration is not None:
            import numpy as np
            latent, rollout = np.asarray(self.calibration["latent"]), np.asarray(self.calibration["rollout"])
            ylabels = self.calibration["ylabels"]
        fig = plots.latent_figure(self.time + _t0(self), latent, rollout, self.train_frames, self.states,
                                  window=int(self.settings.get("window", 0)) or None, ylabels=ylabels,
                                  angles=plots.angle_states(self), measured=bool(self.meta.get("direct")),
                                  pyplot=True)
        if path is not None:
            fig.savefig(path, dpi=plots.DPI)
        return fig

    # ------------------------------------------------------------------ keeping it
    def save(self, folder: str | Path) -> Path:
        """Write the files of `fitode VIDEO`'s folder that a result alone can make: result.json,
        fit.json (reload with Result.load), estimates.csv, track.csv, latent.png, and params.png and
        loss.png where an encoder was trained (track.png and frames.png need the video: `fitode VIDEO` draws them). The folder
        must not exist or be empty: nothing is overwritten. Returns the folder."""
        from fitode import report as rep
        from fitode.output import _check_out_dir, _plots_for_result
        from fitode.tables import write_run_tables
        target = _check_out_dir(folder)
        target.mkdir(parents=True, exist_ok=True)
        report = self.report()
        report["out_dir"] = str(target)
        self.save_json(target / "fit.json")
        done: list[str] = []
        report["warnings"] = list(report["warnings"]) + _plots_for_result(target, self, report, done, _t0(self))
        report["files"] = sorted(["result.json", "fit.json", *done, *write_run_tables(report, target)])
        rep.write_json(report, target / "result.json")
        return target

    @classmethod
    def load(cls, path: str | Path) -> "Result":
        """A result saved by save (its folder) or any fit.json."""
        p = Path(path)
        return cls.of(FitResult.load(p / "fit.json" if p.is_dir() else p))


def _t0(result: FitResult) -> float:
    """Video time of the first frame fitted (a path read from --start on), 0 for frames."""
    return float((result.meta.get("input") or {}).get("first_frame_time_s") or 0.0)


def report_of(result: FitResult) -> dict[str, Any]:
    """result.json's content for a result without the command line's header (fitode.report)."""
    from fitode._version import __version__
    from fitode import report as rep
    from fitode.interrupted import mark_report
    try:
        from fitode.eqparse import parse
        ode = parse(result.equation, fix=result.fixed, free=list(result.parameters))
        analysis = rep.analysis_dict(rep.identifiability(ode))
    except Exception:  # noqa: BLE001 - the analysis is advice (units of a latent); the numbers stand without it
        analysis = None
    inp = dict(result.meta.get("input") or {})
    inp.setdefault("dt", result.dt)
    inp.setdefault("frames_used", len(result.time))
    report: dict[str, Any] = {
        "status": "complete", "fitode_version": __version__, "input": inp,
        "equation": {"text": result.equation, "states": list(result.states), "learnable": list(result.parameters),
                     "fixed": dict(result.fixed), "units": {n: e.unit for n, e in result.parameters.items() if e.unit}},
        "identifiability": analysis, "settings": dict(result.settings), "warnings": [], "notes": [], "files": [],
    }
    rep.complete_report(report, result, analysis, _t0(result))
    if result.meta.get("comparison"):
        report["comparison"] = result.meta["comparison"]
    mark_report(report, result)
    return report
