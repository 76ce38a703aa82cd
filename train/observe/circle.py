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
# neighbouring frames' misses hang together (a blur, a shadow, a slanted swing): a bend's
# significance counts one independent miss per this many points
CORRELATED = 10
JACKKNIFE_BLOCKS = 8  # stretches of time the radius's jackknife leaves out in turn
JACKKNIFE_MIN = 8  # points per stretch below which there is no jackknife (a path of under 64 points)


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
    radius_error: float = np.inf  # the radius's relative standard error (radius_error())

    points: int = 0  # how many points it was fitted to
    # the centre's covariance (var x, cov xy, var y), widened as the radius's error is: the angles are
    # read about the centre alone, so this is what the measurement's geometry leaves uncertain
    centre_cov: tuple[float, float, float] | None = None

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
    are too few: under 5). The points in time order (a track): the radius's error leaves out
    stretches of time in turn (radius_error)."""
    xy = np.asarray(xy, dtype=np.float64)
    xy = xy[np.isfinite(xy).all(axis=1)]
    got = _geometric(xy)
    if got is None:
        return None
    centre, radius, scale, jac = got
    angles = np.unwrap(np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0]))
    lo, hi = np.percentile(angles, [1, 99])  # a stray frame does not widen the span
    span = float(hi - lo)
    sagitta = radius * (1 - np.cos(min(span, 2 * np.pi) / 2)) if span < np.pi else radius
    error, cov = radius_error(xy, centre, radius, scale, jac)
    return Circle((float(centre[0]), float(centre[1])), radius, scale, float(sagitta), span, error, len(xy), cov)


def _geometric(xy: np.ndarray) -> tuple[np.ndarray, float, float, np.ndarray | None] | None:
    """The robust geometric fit of finite points (T, 2): centre, radius, the robust scatter and the
    last round's Jacobian (None where no round gave a finite fit); None where they lie on a line."""
    from scipy.optimize import least_squares

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
    return params[:2] + mean, abs(float(params[2])), scale, jac


def radius_error(xy: np.ndarray, centre: np.ndarray, radius: float, scale: float,
                 jac: np.ndarray | None) -> tuple[float, tuple[float, float, float] | None]:
    """The radius's relative standard error, the larger of two readings of how the misses hang
    together (inf where neither can be made), and the centre's covariance widened by the same
    factor over least squares' (None where there is no Jacobian):
    - along the arc: least squares' error (the Jacobian's, times the scatter) widened by the
      misses' correlation time along the arc (residuals.correlation_time of the distances sorted
      by angle): a slanted swing or a bob whose look turns with the angle
      misses the circle alike at neighbouring places, however far apart in time;
    - in time: a delete-a-block jackknife over JACKKNIFE_BLOCKS stretches of the path: a miss that
      drifts in time (a bob that twists, a pivot that sways) while the swing decays and covers
      less of the arc bends the arc it is read on.
    A fixed count of CORRELATED points per independent miss made the real apple's radius 9.2%
    uncertain, where its jackknife says 2.1% and its misses along the arc 3.2%."""
    from ..residuals import correlation_time

    error, cov = np.inf, None
    if jac is not None:
        try:
            d = np.hypot(xy[:, 0] - centre[0], xy[:, 1] - centre[1]) - radius
            order = np.argsort(np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0]))
            cov = np.linalg.inv(jac.T @ jac) * scale ** 2 * correlation_time(d[order])
            # a near-singular inverse (a straight or noise-free path) can give no positive variance
            error = float(np.sqrt(cov[2, 2])) / max(radius, 1e-12) if cov[2, 2] > 0 else np.inf
        except np.linalg.LinAlgError:
            cov = None
    n, g = len(xy), JACKKNIFE_BLOCKS
    left = []
    if n >= JACKKNIFE_MIN * g:
        edges = np.linspace(0, n, g + 1).astype(int)
        left = [_geometric(np.delete(xy, np.s_[edges[k]:edges[k + 1]], axis=0)) for k in range(g)]
    if left and all(f is not None for f in left):
        radii = np.array([f[1] for f in left])
        jack = float(np.sqrt((g - 1) / g * np.sum((radii - radii.mean()) ** 2))) / max(radius, 1e-12)
        if cov is not None and jack > error > 0:
            cov = cov * (jack / error) ** 2
        error = max(error, jack) if np.isfinite(error) else jack
    return error, None if cov is None else (float(cov[0, 0]), float(cov[0, 1]), float(cov[1, 1]))


def _robust_std(r: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(r)))
