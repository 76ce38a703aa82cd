"""Which restarts the estimate comes from."""
from __future__ import annotations

import math

from .result import RunRecord


def select_runs(runs: list[RunRecord], factor: float, statuses: tuple[str, ...] = ("ok",)) -> list[int]:
    """Runs the estimate is taken from: finite, and final loss within `factor` of the lowest."""
    ok = [r for r in runs if r.status in statuses and math.isfinite(r.loss) and r.steps > 0]
    if not ok:
        return []
    best = min(r.loss for r in ok)  # MSE and KL are both >= 0
    return [r.index for r in ok if r.loss <= best * factor + 1e-12]
