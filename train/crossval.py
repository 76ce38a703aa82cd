"""Blocked cross-validation along time: how well an equation predicts stretches of a measured path
it was not fitted on, and which of several candidate equations predicts them best.

The path (T, k) is cut into K contiguous blocks. For each block, one trajectory of the equation is
fitted to the frames outside it (the trajectory fitter with those frames kept, trajectory.py: it
runs through the held-out block, so a block in the middle is interpolated by the equation and the
last one extrapolated), and its misfit inside the block is the block's held-out error: the RMS of
prediction minus path, in units of each column's spread over the whole path (every candidate
reads the same path, so the unit is shared). Frames next to each other are correlated, so the
information criteria that count frames as independent samples (AIC, BIC) overstate every
difference; a block as long as a fifth of the clip is held out whole, so what it measures is the
equation's prediction, not the noise's.

Ranking (rank): the candidate with the lowest held-out error is preferred over each other one only
where the clip can tell: the paired per-block log ratios of their errors have a mean above
TELL_T * their standard error (Student's t at 97.5%, K - 1 degrees of freedom: a one-sided 2.5%
chance to prefer one of two equally good candidates by luck) and above log(1 + MIN_GAIN) (a
prediction better by less than MIN_GAIN is what a different fit of the same frames gives).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .direct import full_fit
from .trajectory import TrajectoryFit, long_options

BLOCKS = 5
MIN_GAIN = 0.10
# Student's t at 97.5% by degrees of freedom (K - 1 for K blocks)
_T975 = {2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228, 11: 2.201}
MIN_BLOCKS, MAX_BLOCKS = 3, 12
MIN_BLOCK_FRAMES = 3


@dataclass
class HeldOut:
    """One candidate's blocked cross-validation on one path."""

    blocks: list[tuple[int, int]]  # [first, last) frames of each held-out block
    errors: np.ndarray  # (K,) held-out RMS error per block, in spreads of the path; inf where the fit failed
    values: list[dict[str, float] | None] = field(default_factory=list)  # the constants fitted without each block

    @property
    def error(self) -> float:
        """The held-out RMS error over every block's frames (blocks weighted by their length)."""
        n = np.array([b - a for a, b in self.blocks], dtype=float)
        return float(math.sqrt(np.sum(n * self.errors ** 2) / n.sum())) if np.all(np.isfinite(self.errors)) \
            else math.inf

    def to_dict(self) -> dict:
        return {"error": self.error, "blocks": [list(b) for b in self.blocks],
                "errors": [float(e) for e in self.errors], "values": self.values}


def blocks_of(n_frames: int, k: int = BLOCKS) -> list[tuple[int, int]]:
    """k contiguous blocks covering n_frames, their lengths differing by at most one frame."""
    if not MIN_BLOCKS <= k <= MAX_BLOCKS:
        raise ValueError(f"blocks must be between {MIN_BLOCKS} and {MAX_BLOCKS}, got {k}")
    if n_frames < k * MIN_BLOCK_FRAMES:
        raise ValueError(f"{n_frames} frames are too few for {k} blocks of at least {MIN_BLOCK_FRAMES}")
    edges = np.round(np.linspace(0, n_frames, k + 1)).astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def held_out(system, params: Mapping, x: np.ndarray, dt: float, values: Mapping[str, float], *,
             fitted_gauge: Mapping | None = None, gauge: Mapping | None = None, blocks: int = BLOCKS,
             integrator: str = "rk4", substeps: int = 1) -> HeldOut:
    """The blocked cross-validation of `system` on the path x (T, k): each block's frames left out
    of one trajectory fit started from `values` (the constants of a fit of the whole path) and
    `fitted_gauge` (that fit's {state: {scale, offset}}, in x's units; a learned scale is held at
    it, as direct.full_fit holds the windows'), then predicted. gauge: the fit's gauge plan
    ({state: StateGauge}), None for a path in the state's own units."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    spread = np.maximum(x.std(axis=0), 1e-300)
    lead = TrajectoryFit(values=dict(values), errors={}, misfit=0.0, residuals=np.zeros_like(x), converged=True,
                         gauge=dict(fitted_gauge) if fitted_gauge else None)
    cut = blocks_of(len(x), blocks)
    errors, found = [], []
    for a, b in cut:
        keep = np.ones(len(x), dtype=bool)
        keep[a:b] = False
        fit = full_fit(system, params, x, dt, lead, gauge=gauge, keep=keep, integrator=integrator,
                       substeps=substeps, **long_options(len(x)))
        if fit is None or not np.all(np.isfinite(fit.residuals[a:b])):
            errors.append(math.inf)
            found.append(None)
            continue
        errors.append(float(np.sqrt(np.mean((fit.residuals[a:b] / spread) ** 2))))
        found.append({n: float(fit.values[n]) for n in system.learnable})
    return HeldOut(cut, np.array(errors), found)


@dataclass
class Ranking:
    """Which candidate predicts held-out stretches best, and whether the clip can tell."""

    order: list[int]  # candidates, best held-out error first
    preferred: int | None  # None: the clip cannot tell the best from the runner-up
    verdicts: list[str]  # one per candidate: "preferred", "worse", "cannot tell apart", "failed"
    reason: str
    ratios: list[dict[str, float] | None]  # per candidate: its paired comparison with the best (None for the best)


def rank(held: Sequence[HeldOut], names: Sequence[str] | None = None) -> Ranking:
    """The ranking of candidates by their held-out errors (module docstring: the rule). names:
    how the reason names each candidate (default "candidate 1", ...)."""
    if len(held) < 2:
        raise ValueError("a ranking needs at least two candidates")
    names = list(names) if names is not None else [f"candidate {i + 1}" for i in range(len(held))]
    scores = [h.error for h in held]
    order = sorted(range(len(held)), key=lambda i: scores[i])
    best = order[0]
    verdicts = ["failed" if not math.isfinite(s) else "worse" for s in scores]
    ratios: list[dict[str, float] | None] = [None] * len(held)
    if not math.isfinite(scores[best]):
        return Ranking(order, None, verdicts, "every candidate's held-out fit failed", ratios)
    tied = []
    for j in order[1:]:
        if not math.isfinite(scores[j]):
            continue
        ratios[j] = _paired(held[best].errors, held[j].errors)
        if not ratios[j]["tells"]:
            tied.append(j)
            verdicts[j] = "cannot tell apart"
    if tied:
        verdicts[best] = "cannot tell apart"
        r = ratios[tied[0]]
        reason = (f"this clip cannot tell {names[best]} and {names[tied[0]]} apart: held-out error "
                  f"{scores[best]:.4g} against {scores[tied[0]]:.4g}, {r['gain'] * 100:+.1f}% "
                  f"(+-{r['uncertainty'] * 100:.1f}% over {len(held[best].errors)} blocks); a real difference "
                  f"needs more than {max(r['threshold'], MIN_GAIN) * 100:.0f}%")
        return Ranking(order, None, verdicts, reason, ratios)
    verdicts[best] = "preferred"
    runner = next((j for j in order[1:] if ratios[j] is not None), None)
    if runner is None:
        reason = f"{names[best]} is the only candidate whose held-out fits succeeded"
    else:
        r = ratios[runner]
        reason = (f"{names[best]} predicts held-out stretches better: held-out error {scores[best]:.4g} against "
                  f"{scores[runner]:.4g} for {names[runner]}, whose error is {r['gain'] * 100:.0f}% larger "
                  f"(+-{r['uncertainty'] * 100:.0f}% over {len(held[best].errors)} blocks)")
    return Ranking(order, best, verdicts, reason, ratios)


def _paired(best: np.ndarray, other: np.ndarray) -> dict[str, float]:
    """The paired comparison of two candidates' per-block errors: the mean log ratio (other over
    best) as a relative gain, its standard error, and whether the clip tells them apart."""
    d = np.log(np.maximum(other, 1e-300) / np.maximum(best, 1e-300))
    k = len(d)
    se = float(d.std(ddof=1) / math.sqrt(k)) if k > 1 else math.inf
    t = _T975.get(k - 1, 2.0)
    mean = float(d.mean())
    tells = bool(mean > t * se and mean > math.log1p(MIN_GAIN))
    return {"gain": math.expm1(mean), "uncertainty": math.expm1(se), "threshold": math.expm1(t * se),
            "t": mean / se if se > 0 else math.inf, "tells": tells}
