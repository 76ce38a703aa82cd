"""The tables a run leaves to take away: estimates.csv and track.csv, written from result.json's report.

estimates.csv: one row per learnable constant, ESTIMATE_COLUMNS (restart_spread is result.json's
"std": the spread of the restarts, not the uncertainty; the interval is that).
track.csv: one row per frame used: time_s (video seconds), frame (index in the source video),
then per state S: S (the measured state in its unit, "S [px]" or "S [m]" with --scale, y up; a free encoder's
latent; or the calibrated value in physical units when --calibrate was applied), S_fit (the equation's rollout), S_residual (S - S_fit), then what was measured in the
source video's pixels where result.json's "measurement" has it (MEASURED_COLUMNS: the tracked
point x_px, y_px; the apparent radius radius_px).

Both are read from the report alone, so their numbers are result.json's numbers (floats written
with repr, which round-trips exactly); nothing here judges or recomputes an estimate.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any, Iterable, Mapping

from fitode.jsonio import to_jsonable, write_text

# interval_low/high: the 95% interval (empty where none was made). restart_spread: the standard
# deviation of the restarts' final values that the estimate averages (0 for one): how alike the
# restarts ended, no uncertainty of the value (that is the interval)
ESTIMATE_COLUMNS = ("constant", "value", "interval_low", "interval_high", "restart_spread", "unit", "calibrated",
                    "verdict", "reason")
# equation: the one fitted, as typed (of several candidates, the one the comparison reports: fitode.compare)
BATCH_ESTIMATE_COLUMNS = ("job", "video", "equation") + ESTIMATE_COLUMNS


def csv_text(header: Iterable[str], table: Iterable[Iterable[Any]]) -> str:
    """CSV with None as an empty cell and floats as repr (exact round trip)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(header))
    for line in table:
        w.writerow(["" if v is None else (repr(v) if isinstance(v, float) else v) for v in line])
    return buf.getvalue()


def estimate_rows(parameters: Mapping[str, Mapping[str, Any]]) -> list[list[Any]]:
    """ESTIMATE_COLUMNS rows from result.json's "parameters" (or the batch's copy of it)."""
    rows = []
    for name, est in parameters.items():
        interval = est.get("interval")
        low, high = (interval[0], interval[1]) if isinstance(interval, (list, tuple)) and len(interval) == 2 \
            else (None, None)
        # a value in the latent's arbitrary units has none of the equation file's unit (as the printed table)
        unit = "latent units" if est.get("latent_units") else est.get("unit")
        rows.append([name, est.get("value"), low, high, est.get("std"), unit,
                     bool(est.get("calibrated")), est.get("verdict"), est.get("verdict_reason")])
    return rows


def estimates_csv(report: Mapping[str, Any]) -> str:
    return csv_text(ESTIMATE_COLUMNS, estimate_rows(report.get("parameters") or {}))


# result.json "measurement" key -> its columns in track.csv (source pixels, one value per frame)
MEASURED_COLUMNS = {"track": ("x_px", "y_px"), "radii": ("radius_px",)}


def track_header(states: Iterable[str], measured: Iterable[str] = (),
                 units: Mapping[str, str] | None = None) -> list[str]:
    """The columns; a state measured in a unit (px, or m with --scale) says it in brackets: "y [px]",
    "y_fit [px]" (the tracked point's x_px, y_px are the image's, y down)."""
    states, units = list(states), dict(units or {})
    unit = {s: f" [{units[s]}]" if units.get(s) else "" for s in states}
    return (["time_s", "frame"] + [f"{s}{unit[s]}" for s in states] + [f"{s}_fit{unit[s]}" for s in states]
            + [f"{s}_residual{unit[s]}" for s in states] + [c for key in measured for c in MEASURED_COLUMNS[key]])


def _measured(report: Mapping[str, Any], n: int) -> tuple[list[str], list[list[Any]]]:
    """The measurement record's per-frame series that have n values: their keys and, per frame, the cells."""
    m = report.get("measurement") or {}
    keys = [k for k in MEASURED_COLUMNS if isinstance(m.get(k), list) and len(m[k]) == n]
    rows = []
    for i in range(n):
        cells: list[Any] = []
        for k in keys:
            v = m[k][i]  # a point [x, y], a number, or None where nothing was seen
            cells += [None] * len(MEASURED_COLUMNS[k]) if v is None else list(v) if isinstance(v, list) else [v]
        rows.append(cells)
    return keys, rows


def track_csv(report: Mapping[str, Any]) -> str | None:
    """track.csv's text, or None when the report has no trajectory (a failed or interrupted run)."""
    traj = report.get("trajectory")
    if not traj:
        return None
    states = list(traj["states"])
    inp = report.get("input") or {}
    fps, stride = inp.get("fps"), int(inp.get("stride") or 1)
    first = int(round(float(inp.get("first_frame_time_s") or 0.0) * fps)) if fps else 0
    keys, measured = _measured(report, len(traj["time"]))
    frames = traj.get("frames")  # the source's numbers where the reader kept them (fitode.pipeline)
    if not (isinstance(frames, list) and len(frames) == len(traj["time"])):
        frames = [first + i * stride for i in range(len(traj["time"]))]
    table = []
    for i, (t, z, r) in enumerate(zip(traj["time"], traj["latent"], traj["rollout"])):
        resid = [_minus(a, b) for a, b in zip(z, r)]
        table.append([t, frames[i], *z, *r, *resid, *(measured[i] if keys else [])])
    return csv_text(track_header(states, keys, traj.get("state_units")), table)


def write_run_tables(report: Mapping[str, Any], folder: Path) -> list[str]:
    """Write estimates.csv and (when there is a trajectory) track.csv; the names written."""
    report = to_jsonable(report)  # NaN -> empty cell, as result.json writes it null
    write_text(estimates_csv(report), folder / "estimates.csv")
    done = ["estimates.csv"]
    track = track_csv(report)
    if track is not None:
        write_text(track, folder / "track.csv")
        done.append("track.csv")
    return done


def batch_estimates_csv(rows: Iterable[Any]) -> str:
    """One table for a whole batch: BATCH_ESTIMATE_COLUMNS, one row per job and constant (SummaryRow's)."""
    table = [[r.name, r.video, r.details.get("equation"), *line] for r in rows for line in estimate_rows(r.parameters)]
    return csv_text(BATCH_ESTIMATE_COLUMNS, table)


def _minus(a: Any, b: Any) -> float | None:
    # the rollout of a run that went non-finite is null in result.json: no residual there
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)):
        return None
    return a - b
