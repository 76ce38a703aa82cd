"""The circle a path bends about (the arc of a swing): an algebraic fit, refined geometrically
with a robust loss, and how clearly the path bends (its sagitta against the fit's scatter).

The algebraic fit (Kasa: x^2 + y^2 + D x + E y + F = 0, linear least squares) is exact for
points on a circle and needs no start, but it leans towards small circles when the arc is short
and noisy. The geometric fit (distances to the circle) with a soft-L1 loss, started there, has
no such bias, and frames whose centroid jumped to something else (a hand, a shadow) pull it
little. The centre may lie far outside the frame: a pendulum's pivot above it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ROUNDS = 3  # geometric refinements, each with the loss's scale from the last one's residuals
SOFT = 2.0  # the soft-L1 loss turns linear from this many robust standard deviations
# neighbouring frames' misses hang together (a blur, a shadow, a slanted swing): the radius's
# standard error counts one independent miss per this many points
CORRELATED = 10


@dataclass(frozen=True)
class Circle:
    """centre (x, y) and radius in the path's units; scatter: the robust standard deviation of
    the points' distances from the circle (1.4826 x their median absolute value); sagitta: how
    far the arc the path covers bows from its chord, radius x (1 - cos(half its angular span))."""

    centre: tuple[float, float]
    radius: float
    scatter: float
    sagitta: float
    span: float  # the angle the path covers about the centre, radians
    radius_error: float = np.inf  # the radius's relative standard error (misses hanging together over CORRELATED points)

    points: int = 0  # how many points it was fitted to

    @property
    def bend(self) -> float:
        """The sagitta in units of the scatter: large where the path clearly bends about a
        centre, about 1 or less for a straight or shapeless path."""
        return self.sagitta / max(self.scatter, 1e-12)

    @property
    def significance(self) -> float:
        """The sagitta in units of its own uncertainty, the scatter over the root of the number
        of independent points (one per CORRELATED): a long clip fixes a shallow bend."""
        return self.bend * np.sqrt(max(self.points, 1) / CORRELATED)

    @property
    def thinness(self) -> float:
        """The scatter across the arc over the length of arc the path covers, up to a radian of
        it: small where the path runs along the circle, large where it fills an area (a figure of
        eight, which a wide circle crosses in every direction)."""
        return self.scatter / max(self.radius * min(self.span, 1.0), 1e-12)


def algebraic_circle(xy: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Kasa's fit: the centre (2,) and radius, or None where the points lie on a line."""
    xy = np.asarray(xy, dtype=np.float64)
    mean = xy.mean(axis=0)
    p = xy - mean  # centred, so the normal equations stay well conditioned
    spread = np.linalg.svd(p, compute_uv=False)
    if len(spread) < 2 or spread[1] <= 1e-9 * spread[0]:
        return None  # on one line exactly
    a = np.column_stack([p, np.ones(len(p))])
    b = -(p ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    centre = -sol[:2] / 2
    r2 = float(centre @ centre - sol[2])
    spread = float(np.sqrt((p ** 2).sum(axis=1).mean())) + 1e-12
    if not np.all(np.isfinite(centre)) or r2 <= 0 or np.sqrt(r2) > 1e6 * spread:
        return None
    return centre + mean, float(np.sqrt(r2))


def fit_circle(xy: np.ndarray) -> Circle | None:
    """The circle (T, 2) points bend about, fitted robustly; None where they lie on a line (or
    are too few: under 5)."""
    from scipy.optimize import least_squares

    xy = np.asarray(xy, dtype=np.float64)
    xy = xy[np.isfinite(xy).all(axis=1)]
    if len(xy) < 5:
        return None
    start = algebraic_circle(xy)
    if start is None:
        return None
    mean = xy.mean(axis=0)
    p = xy - mean
    params = np.array([*(start[0] - mean), start[1]])

    def distances(q: np.ndarray) -> np.ndarray:
        return np.hypot(p[:, 0] - q[0], p[:, 1] - q[1]) - q[2]

    scale = _robust_std(distances(params))
    jac = None
    for _ in range(ROUNDS):
        fit = least_squares(distances, params, loss="soft_l1", f_scale=SOFT * max(scale, 1e-9), x_scale="jac")
        if not np.all(np.isfinite(fit.x)):
            break
        params, jac = fit.x, fit.jac
        scale = _robust_std(distances(params))
    centre, radius = params[:2] + mean, abs(float(params[2]))
    angles = np.unwrap(np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0]))
    lo, hi = np.percentile(angles, [1, 99])  # a stray frame does not widen the span
    span = float(hi - lo)
    sagitta = radius * (1 - np.cos(min(span, 2 * np.pi) / 2)) if span < np.pi else radius
    error = np.inf
    if jac is not None:
        try:
            error = float(np.sqrt(np.linalg.inv(jac.T @ jac)[2, 2] * CORRELATED) * scale / max(radius, 1e-12))
        except np.linalg.LinAlgError:
            pass
    return Circle((float(centre[0]), float(centre[1])), radius, scale, float(sagitta), span, error, len(xy))


def _robust_std(r: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(r)))
