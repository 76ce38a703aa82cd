"""Which restarts the estimate comes from, and why each other one was left out."""
from __future__ import annotations

import math

from .result import RunRecord


SCORE_MARGIN = 0.1


def selection(runs: list[RunRecord], factor: float,
              statuses: tuple[str, ...] = ("ok",)) -> tuple[list[int], dict[int, str]]:
    """The runs the estimate is taken from, and {index: why} for every run left out.

    First by what the latent can tell apart: of the finite runs, those whose score is within
    SCORE_MARGIN of the best score (a run with no score is judged by its loss alone). The loss
    cannot judge this: the harmonic trap's folded latent may reach a lower loss than the truth.
    Then by the loss: of those, the runs whose final loss is within `factor` of their lowest.
    """
    why: dict[int, str] = {}
    ok = []
    for r in runs:
        if r.status not in statuses:
            why[r.index] = r.status
        elif not math.isfinite(r.loss) or r.steps == 0:
            why[r.index] = "no finite loss"
        else:
            ok.append(r)
    scored = [r.score for r in ok if r.score is not None and math.isfinite(r.score)]
    if scored:
        top = max(scored)
        for r in ok:
            if r.score is not None and math.isfinite(r.score) and r.score < top - SCORE_MARGIN:
                why[r.index] = f"its score {r.score:.2f} is more than {SCORE_MARGIN:g} below the best ({top:.2f})"
        ok = [r for r in ok if r.index not in why]
    if not ok:
        return [], why
    best = min(r.loss for r in ok)  # MSE and KL are both >= 0
    for r in ok:
        if r.loss > best * factor + 1e-12:
            why[r.index] = f"its loss is more than {factor:g}x the lowest"
    return [r.index for r in ok if r.index not in why], why


def select_runs(runs: list[RunRecord], factor: float, statuses: tuple[str, ...] = ("ok",)) -> list[int]:
    """The runs the estimate is taken from (see selection)."""
    return selection(runs, factor, statuses)[0]
