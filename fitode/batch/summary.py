"""The batch's tables: one row per video (summary) and one per setting (aggregate).

summary.csv columns: name, setting, video, status, error, wall_s, reused, folder, stride, dt, equation
(the stride the job used, which `auto` may choose per video, the resulting time step, and the
equation fitted: of several candidates, the one the comparison reports), then per
constant NAME, NAME.low and NAME.high (its 95% interval), NAME.unit ("latent units" where the
value has none), NAME.restart_spread (the standard deviation of the restarts: no uncertainty),
NAME.verdict (trusted / ambiguous / not trustworthy) and NAME.reason, NAME.true and
NAME.rel_error where a true value is given. aggregate.csv: setting, jobs, complete, failed,
then per constant NAME.mean, NAME.std (sample standard deviation over the setting's complete
videos), NAME.n, NAME.unit, NAME.pooled, NAME.pooled_low, NAME.pooled_high and NAME.pooled_n
(the 95% interval pooled from the videos' intervals: pooled_interval), NAME.true and
NAME.rel_error (of the mean), as the paper's tables report them. estimates.csv: job, video,
equation, then the columns of a run's estimates.csv (fitode.tables), one row per job and constant.

Every file is written to a temporary name and renamed over the old one, so an interrupted
batch never leaves a half-written summary.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable

from fitode.jsonio import write_json, write_text
from fitode.tables import batch_estimates_csv, csv_text

STATUSES = ("complete", "incomplete", "failed", "pending")


@dataclass
class SummaryRow:
    name: str
    setting: str
    video: str
    status: str = "pending"
    error: str | None = None
    wall_s: float | None = None
    reused: bool = False
    folder: str = ""
    parameters: dict[str, dict[str, float | None]] = field(default_factory=dict)
    truth: dict[str, float] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def estimate(self, name: str) -> float | None:
        return (self.parameters.get(name) or {}).get("value")

    def rel_error(self, name: str) -> float | None:
        return rel_error(self.estimate(name), self.truth.get(name))


def rel_error(value: float | None, true: float | None) -> float | None:
    """(estimate - truth) / |truth|, signed; None where either is missing or the truth is 0."""
    if value is None or true is None or true == 0:
        return None
    return (value - true) / abs(true)


def parameter_names(rows: Iterable[SummaryRow]) -> list[str]:
    names: dict[str, None] = {}
    for r in rows:
        names.update(dict.fromkeys(r.parameters))
        names.update(dict.fromkeys(r.truth))
    return list(names)


def counts(rows: Iterable[SummaryRow]) -> dict[str, int]:
    c = {s: 0 for s in STATUSES}
    for r in rows:
        c[r.status] = c.get(r.status, 0) + 1
    return c


def summary_table(rows: list[SummaryRow]) -> tuple[list[str], list[list[Any]]]:
    names = parameter_names(rows)
    has_truth = {n for r in rows for n in r.truth}
    header = ["name", "setting", "video", "status", "error", "wall_s", "reused", "folder", "stride", "dt", "equation"]
    for n in names:
        header += [n, f"{n}.low", f"{n}.high", f"{n}.unit", f"{n}.restart_spread", f"{n}.verdict", f"{n}.reason"]
        header += [f"{n}.true", f"{n}.rel_error"] if n in has_truth else []
    table = []
    for r in rows:
        line: list[Any] = [r.name, r.setting, r.video, r.status, r.error or "",
                           _round(r.wall_s, 3), r.reused, r.folder, r.details.get("stride"), r.details.get("dt"),
                           r.details.get("equation")]
        for n in names:
            p = r.parameters.get(n) or {}
            low, high = p.get("interval") or (None, None)
            line += [p.get("value"), low, high, unit_of(p), p.get("std"), p.get("verdict") or "",
                     p.get("verdict_reason") or ""]
            if n in has_truth:
                line += [r.truth.get(n), r.rel_error(n)]
        table.append(line)
    return header, table


def aggregate(rows: list[SummaryRow]) -> list[dict[str, Any]]:
    """Mean and spread over the videos of each setting (complete jobs only), in manifest order."""
    settings = list(dict.fromkeys(r.setting for r in rows))
    out = []
    for s in settings:
        group = [r for r in rows if r.setting == s]
        ok = [r for r in group if r.status == "complete"]
        entry: dict[str, Any] = {"setting": s, "jobs": len(group), "complete": len(ok),
                                 "failed": sum(r.status == "failed" for r in group), "parameters": {}}
        for n in parameter_names(group):
            vals = [v for v in (r.estimate(n) for r in ok) if v is not None]
            mean = sum(vals) / len(vals) if vals else None
            std = (math.sqrt(sum((v - mean) ** 2 for v in vals) / (len(vals) - 1)) if len(vals) > 1
                   else (0.0 if vals else None))
            truths = {r.truth[n] for r in group if n in r.truth}
            true = truths.pop() if len(truths) == 1 else None
            units = {unit_of(r.parameters.get(n) or {}) for r in ok if n in r.parameters}
            pooled = pooled_interval([(r.parameters[n].get("value"), r.parameters[n].get("interval"))
                                      for r in ok if n in r.parameters])
            entry["parameters"][n] = {"mean": mean, "std": std, "n": len(vals), "true": true,
                                      "rel_error": rel_error(mean, true),
                                      "unit": units.pop() if len(units) == 1 else ("mixed" if units else None),
                                      **pooled}
        out.append(entry)
    return out


def unit_of(p: dict[str, Any]) -> str | None:
    """A job's constant's unit as its table says it ("latent units" where the value has none)."""
    return "latent units" if p.get("latent_units") else p.get("unit")


Z95 = 1.959963984540054  # the normal quantile of a two-sided 95% interval


def pooled_interval(estimates: list[tuple[float | None, list[float] | None]]) -> dict[str, Any]:
    """The 95% interval of the value that several videos of one setting measure: the inverse-
    variance mean of the estimates with a 95% interval (each interval read as value +- 1.96 sigma,
    its wider side), its interval widened by sqrt(chi2 / (n - 1)) where the videos disagree more
    than their intervals say (the Birge ratio, as the Particle Data Group scales a world average).
    {"pooled", "pooled_low", "pooled_high", "pooled_n"}; None values where no video has an interval."""
    pts = [(float(v), max(v - iv[0], iv[1] - v) / Z95) for v, iv in estimates
           if v is not None and iv and all(isinstance(e, (int, float)) and math.isfinite(e) for e in iv)]
    pts = [(v, s) for v, s in pts if s > 0]
    if not pts:
        return {"pooled": None, "pooled_low": None, "pooled_high": None, "pooled_n": 0}
    weights = [1.0 / s ** 2 for _, s in pts]
    centre = sum(w * v for w, (v, _) in zip(weights, pts)) / sum(weights)
    sigma = 1.0 / math.sqrt(sum(weights))
    if len(pts) > 1:
        chi2 = sum(w * (v - centre) ** 2 for w, (v, _) in zip(weights, pts))
        sigma *= max(1.0, math.sqrt(chi2 / (len(pts) - 1)))
    return {"pooled": centre, "pooled_low": centre - Z95 * sigma, "pooled_high": centre + Z95 * sigma,
            "pooled_n": len(pts)}


def aggregate_table(agg: list[dict[str, Any]]) -> tuple[list[str], list[list[Any]]]:
    names: dict[str, None] = {}
    for e in agg:
        names.update(dict.fromkeys(e["parameters"]))
    header = ["setting", "jobs", "complete", "failed"]
    for n in names:
        header += [f"{n}.mean", f"{n}.std", f"{n}.n", f"{n}.unit", f"{n}.pooled", f"{n}.pooled_low",
                   f"{n}.pooled_high", f"{n}.pooled_n", f"{n}.true", f"{n}.rel_error"]
    table = []
    for e in agg:
        line: list[Any] = [e["setting"], e["jobs"], e["complete"], e["failed"]]
        for n in names:
            p = e["parameters"].get(n) or {}
            line += [p.get("mean"), p.get("std"), p.get("n"), p.get("unit"), p.get("pooled"), p.get("pooled_low"),
                     p.get("pooled_high"), p.get("pooled_n"), p.get("true"), p.get("rel_error")]
        table.append(line)
    return header, table


def write_summary(out: Path, rows: list[SummaryRow], meta: dict[str, Any]) -> None:
    """summary.csv, summary.json, aggregate.csv, aggregate.json and estimates.csv (every job's
    estimates in one table, fitode.tables), each replaced atomically."""
    agg = aggregate(rows)
    header, table = summary_table(rows)
    write_text(csv_text(header, table), out / "summary.csv")
    payload = {**meta, "counts": counts(rows), "jobs": [_row_json(r) for r in rows], "aggregate": agg}
    write_json(payload, out / "summary.json")
    header, table = aggregate_table(agg)
    write_text(csv_text(header, table), out / "aggregate.csv")
    write_json({"manifest": meta.get("manifest"), "settings": agg}, out / "aggregate.json")
    write_text(batch_estimates_csv(rows), out / "estimates.csv")


def format_aggregate(agg: list[dict[str, Any]]) -> str:
    """The per-setting table for the terminal: mean ± std over videos, and the error of the mean."""
    names: dict[str, None] = {}
    for e in agg:
        names.update(dict.fromkeys(e["parameters"]))
    header = ["setting", "videos"] + list(names)
    lines = []
    for e in agg:
        cells = [e["setting"], f"{e['complete']}/{e['jobs']}"]
        for n in names:
            p = e["parameters"].get(n) or {}
            if p.get("mean") is None:
                cells.append("-")
                continue
            cell = f"{p['mean']:.4g} ± {p['std']:.2g}"
            if p.get("pooled") is not None:
                cell += f" (pooled {p['pooled']:.4g} [{p['pooled_low']:.4g}, {p['pooled_high']:.4g}])"
            if p.get("rel_error") is not None:
                cell += f" ({p['rel_error'] * 100:+.1f}% vs {p['true']:g})"
            cells.append(cell)
        lines.append(cells)
    widths = [max(len(str(x)) for x in col) for col in zip(header, *lines)]
    fmt = lambda cells: "  ".join(str(c).ljust(w) for c, w in zip(cells, widths)).rstrip()  # noqa: E731
    return "\n".join([fmt(header)] + [fmt(c) for c in lines])


def _row_json(r: SummaryRow) -> dict[str, Any]:
    d = asdict(r)
    d["rel_error"] = {n: r.rel_error(n) for n in r.truth}
    return d


def _round(v: float | None, digits: int) -> float | None:
    return None if v is None else round(v, digits)
