"""One set of constants over every piece of a measured path (train/pieces.py).

Each piece is a trajectory of the equation with a starting state of its own (a release, a bounce:
the state jumps between pieces, so the joins are free); the constants are shared and fitted to all
pieces together, by the interval's batched Levenberg-Marquardt (train/interval.py, _Batch with
pieces), from the constants the longest piece gave. Their standard errors come from the Jacobian,
widened for residuals that hang together from frame to frame, as fit_trajectory's do.

The pieces are then checked against each other: each is fitted alone from the shared constants;
one whose constant lies farther from the shared value than SIGMAS of their combined errors and
APART of the value is a finding (a bounce that also knocks the track, a hand still touching).
Where the others are three or more, a piece is measured against them instead: against their
own weighted mean, with the errors widened by how far they scatter about it beyond their errors
(the Birge ratio, sqrt(chi^2 / dof), at least 1). A tracker whose centroid errs by half a pixel
depending on where the thing is moves every piece's value by more than its residuals say (a
generated cart's flights lie 1 to 3 of their errors from the shared value, its short last flight
near the bumper 5): that is no change of the motion, and the interval is widened by the same
ratio over all pieces (scatter), where the scatter is beyond chance (its chi^2 above its 95%
quantile); one piece far from all the others still stands out of them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from .findings import Finding
from .interval import CENTRE_ITERATIONS, _Batch

SIGMAS = 3.0
APART = 0.02
OTHERS = 3  # a piece is measured against the others' scatter where there are this many
CHANCE = 0.95  # the pieces' scatter widens the interval where its chi^2 lies beyond this quantile
FAR = 0.5   # a piece whose constant lies this share of the pieces' median from it (and SIGMAS of its error)
#             is another motion, where fewer than half the pieces are (other_motions)


@dataclass
class JointFit:
    """The shared constants of the pieces and what each piece alone says."""

    values: dict[str, float]
    errors: dict[str, float]
    misfit: float                   # RMS residual over all pieces, in units of each state's spread
    fitted: np.ndarray              # (T, k) the pieces' trajectories, one after another
    alone: list[dict[str, list[float]] | None]  # per piece: name -> [value, error], None where it is too short
    scatter: dict[str, float] | None = None  # per constant: the pieces' scatter over their errors (>= 1)

    def to_dict(self) -> dict:
        return {"values": self.values, "errors": self.errors, "misfit": self.misfit, "alone": self.alone,
                "scatter": self.scatter}


def fit_pieces(system, params: Mapping, x: np.ndarray, dt: float, spans: Sequence[tuple[int, int]],
               start: Mapping[str, float], *, integrator: str = "rk4", substeps: int = 1) -> JointFit | None:
    """The constants shared by the pieces spans [(a, b), ...] of the path x (T, k), in x's units,
    from `start`; None where they cannot be fitted together."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    parts = [x[a:b] for a, b in spans]
    joined = np.concatenate(parts)
    values, errors, misfit, fitted = _fit(system, params, joined, dt, [len(p) for p in parts], start,
                                          integrator, substeps)
    if values is None:
        return None
    alone = []
    for part in parts:
        v, e, _, _ = _fit(system, params, part, dt, [len(part)], values, integrator, substeps) \
            if len(parts) > 1 else (values, errors, None, None)
        alone.append(None if v is None else {n: [v[n], e[n]] for n in v})
    own = {n: [p[n] for p in alone if p is not None] for n in values}
    return JointFit(values, errors, misfit, fitted, alone,
                    {n: _beyond_chance(own[n]) if len(own[n]) >= OTHERS else 1.0 for n in values})


def other_motions(fit: JointFit, released: bool = False) -> list[int]:
    """The pieces that follow another motion than the rest: one trajectory of the equation explains
    each, but with constants FAR from the centre of the pieces' own (a ball rolling on the floor
    after its bounces, y'' = -g with g near 0 against 9.6 from its flights; a hand that picks it up),
    beyond SIGMAS of its error. The centre: the first piece's where it starts at a release (the
    motion the clip shows starts there), else the median of three or more pieces, and then only
    fewer than half may be another motion. A scatter of a few percent (a tracker's error that
    depends on the place) is the disagreement's finding, not this."""
    idx = [k for k, p in enumerate(fit.alone) if p is not None]
    anchored = released and fit.alone and fit.alone[0] is not None
    if len(idx) < (2 if anchored else 3):
        return []
    out: set[int] = set()
    for name in fit.values:
        v = np.array([fit.alone[k][name][0] for k in idx])
        e = np.array([fit.alone[k][name][1] for k in idx])
        centre = float(fit.alone[0][name][0]) if anchored else float(np.median(v))
        far = (np.abs(v - centre) > FAR * abs(centre)) & (np.abs(v - centre) > SIGMAS * e)
        out.update(k for k, f in zip(idx, far) if f)
    return sorted(out) if anchored or 2 * len(out) < len(idx) else []


def _pooled(pairs) -> tuple[float, float, float]:
    """The weighted mean of [value, error] pairs, its error, and their Birge ratio (at least 1)."""
    v = np.array([p[0] for p in pairs], dtype=float)
    w = 1.0 / np.maximum(np.array([p[1] for p in pairs], dtype=float), 1e-300) ** 2
    mean = float(np.sum(w * v) / np.sum(w))
    chi2 = float(np.sum(w * (v - mean) ** 2))
    return mean, float(1.0 / math.sqrt(np.sum(w))), max(1.0, math.sqrt(chi2 / max(len(v) - 1, 1)))


def _beyond_chance(pairs) -> float:
    """The Birge ratio of [value, error] pairs where their chi^2 lies beyond its CHANCE quantile for
    their degrees of freedom, else 1: pieces whose errors are right scatter by a ratio above 1 half
    the time, and widening the interval by it then made the joint one no narrower than the best
    flight's (a generated cart's 6 flights: ratio 1.38, chi^2 9.5 for 5, p 0.09)."""
    from scipy.stats import chi2

    ratio = _pooled(pairs)[2]
    dof = len(pairs) - 1
    return ratio if dof > 0 and ratio ** 2 * dof > chi2.ppf(CHANCE, dof) else 1.0


def disagreement(fit: JointFit, spans: Sequence[tuple[int, int]], dt: float, offset: int = 0) -> list[Finding]:
    """A finding for each constant on which a piece disagrees with the shared value beyond both
    errors."""
    out = []
    for name, value in fit.values.items():
        apart = []
        for k, ((a, b), own) in enumerate(zip(spans, fit.alone)):
            if own is None or len(spans) < 2:
                continue
            v, e = own[name]
            others = [p[name] for j, p in enumerate(fit.alone) if j != k and p is not None]
            centre, error, wide = _pooled(others) if len(others) >= OTHERS else (value, fit.errors[name], 1.0)
            gap = abs(v - centre)
            if gap > APART * max(abs(value), 1e-12) and gap > SIGMAS * wide * math.hypot(e, error):
                apart.append(f"{v:.4g} +- {e:.2g} on {(a + offset) * dt:.2f}-{(b + offset) * dt:.2f} s")
        if apart:
            out.append(Finding("ambiguous", f"the pieces do not share one {name}: {value:.4g} +- "
                               f"{fit.errors[name]:.2g} from all of them, " + "; ".join(apart)
                               + " (in the fit's own units): something changes the motion between them", (name,)))
    return out


def _fit(system, params, x: np.ndarray, dt: float, lengths: list[int], start: Mapping[str, float],
         integrator: str, substeps: int):
    try:
        batch = _Batch(system, params, x, dt, integrator, substeps, lengths)
        if batch.T < batch.p + 2:
            return None, None, None, None
        theta0 = np.concatenate([[float(start[n]) for n in batch.names], batch.starts(x)])[None]
        theta = batch.gauss_newton(theta0, x[None], 4 * CENTRE_ITERATIONS)
        if len(lengths) > 1 and np.all(np.isfinite(theta)):
            batch.weigh_pieces(x - batch.roll(theta)[0])  # each piece at its own noise
            theta = batch.gauss_newton(theta, x[None], 4 * CENTRE_ITERATIONS)
        if not np.all(np.isfinite(theta)):
            return None, None, None, None
        rolled, jac = batch.jacobian(theta)
    except (ValueError, RuntimeError, FloatingPointError, np.linalg.LinAlgError):
        return None, None, None, None
    r = ((rolled[0] - x) * batch.weight).reshape(-1)
    dof = max(r.size - batch.p, 1)
    lag = float(r[1:] @ r[:-1] / max(float(r @ r), 1e-300)) if r.size > 2 else 0.0
    lag = min(max(lag, 0.0), 0.95)
    cov = np.linalg.pinv(jac[0] @ jac[0].T, rcond=1e-13) * float(r @ r) / dof * (1 + lag) / (1 - lag)
    values = {n: float(theta[0, i]) for i, n in enumerate(batch.names)}
    errors = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(batch.names)}
    misfit = float(np.sqrt(np.mean(((rolled[0] - x) * batch.state_weight) ** 2)))
    if not all(math.isfinite(v) for v in [*values.values(), *errors.values(), misfit]):
        return None, None, None, None
    return values, errors, misfit, rolled[0]
