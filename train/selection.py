"""Which restarts the estimate comes from."""
from __future__ import annotations

import math

from .result import RunRecord


SCORE_MARGIN = 0.1


def select_runs(runs: list[RunRecord], factor: float, statuses: tuple[str, ...] = ("ok",)) -> list[int]:
    """Runs the estimate is taken from.

    First by what the latent can tell apart: of the finite runs, those whose score is within
    SCORE_MARGIN of the best score (a run with no score is judged by its loss alone). The loss
    cannot judge this: the harmonic trap's folded latent may reach a lower loss than the truth.
    Then by the loss: of those, the runs whose final loss is within `factor` of their lowest.
    """
    ok = [r for r in runs if r.status in statuses and math.isfinite(r.loss) and r.steps > 0]
    scored = [r.score for r in ok if r.score is not None and math.isfinite(r.score)]
    if scored:
        top = max(scored)
        ok = [r for r in ok if r.score is None or not math.isfinite(r.score) or r.score >= top - SCORE_MARGIN]
    if not ok:
        return []
    best = min(r.loss for r in ok)  # MSE and KL are both >= 0
    return [r.index for r in ok if r.loss <= best * factor + 1e-12]
