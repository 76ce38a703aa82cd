"""Which restarts the estimate comes from, and why each other one was left out."""
from __future__ import annotations

import math

from .result import RunRecord


SCORE_MARGIN = 0.1
AGREE_TOL = 0.05  # restarts agree where they lie within this share of the estimate
RIVAL_MISS = 10.0  # a restart that scores alike is a rival only if it fits the latent about as well
# (its window error over the latent's variance within this factor: the loss would mix in the KL term,
# which differs between right fits of a one-way motion)


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


def rivals(result, name: str, tol: float = AGREE_TOL) -> list[RunRecord]:
    """The restarts left out that tell the frames apart as well as the kept ones (score within
    SCORE_MARGIN of their best), fit their latent about as well (RIVAL_MISS) and ended more than
    tol (relative) from the estimate, compared in the units the runs' values are in (a calibrated
    constant's latent value). [] where restarts are not scored: a measured latent is the same line
    for every restart, so the loss compares them directly and the ones left out fit it worse."""
    est = result.parameters[name]
    value = est.latent_value if est.calibrated and est.latent_value is not None else est.value
    sel = [r for r in result.runs if r.index in result.selected]
    scores = [r.score for r in sel if r.score is not None and math.isfinite(r.score)]
    if not scores:
        return []
    misses = [r.miss for r in sel if r.miss is not None]
    best_miss = min(misses) if misses else math.inf
    return [r for r in result.runs if r.index not in result.selected and r.status == "ok" and name in r.final
            and r.score is not None and r.score >= max(scores) - SCORE_MARGIN
            and (r.miss is None or r.miss <= RIVAL_MISS * best_miss)
            and abs(r.value(name) - value) > tol * max(abs(value), 1e-12)]
