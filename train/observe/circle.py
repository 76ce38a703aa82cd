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


# a path on one arc and, in some frames, nearer its centre along the same directions (a pendulum
# whose faint bob the change loses, which then centres on its string): the outer arc holds at least
# MIN_SHARE of the points and fits THINNER times tighter than one circle through all of them, and
# the inner points' directions from its centre follow those of the outer points next to them in
# time within FOLLOW times the outer points' own step from frame to frame
MIN_SHARE = 0.1
THINNER = 3.0
FOLLOW = 2.0
STRAY_RUN = 3  # the longest run of frames inside the arc, off its direction, read from its neighbours
HALF = 0.5  # the share of the inner points that must follow the arc's directions
ONE_ARC = 0.01  # one circle whose scatter is at most this share of its radius: a path on one arc
NEAR = 4.0  # scatters (at least a pixel) within which a point is on the outer arc


def on_one_radius(xy: np.ndarray) -> tuple[np.ndarray, int, int]:
    """The path (T, 2) with its points nearer the centre of the arc the rest lie on carried out to
    that arc along their direction from the centre, how many were, and how many inside it that
    went their own way were read from the arc's neighbours in time: where a pendulum's faint
    bob is lost, the change is its string's, whose centroid lies on the same line from the pivot,
    so the angle is the same (a generated light bob on a light wall with a dark string, 54
    degrees, 135x240, coverage.py seed 10: the change was the bob in 27% of the frames and the
    string in the rest; one circle through both bowed 1.9x its scatter and no angle was read).
    A path on one arc, or most of whose inner points go their own way, comes back as it is, with
    0 and 0."""
    xy = np.asarray(xy, dtype=np.float64)
    ok = np.isfinite(xy).all(axis=1)
    pts = xy[ok]
    if len(pts) < 20:
        return xy, 0, 0
    one = _geometric(pts)
    if one is None:
        return xy, 0, 0
    if one[2] <= ONE_ARC * one[1]:  # on one arc, its few strays the mending's (the bob clip's 1844 frames)
        return xy, 0, 0
    # one circle through the arc and the points inside it centres between them. Two starts: the
    # centre about which a point's direction runs most smoothly in time whichever distance it is at
    # (the arc a minority), and the circle through three of the points that most others lie on
    # (the arc most of them); the tighter arc wins
    best = None
    for centre, radius in (_smoothest_centre(pts), None), _consensus_circle(pts):
        got = _outer_arc(pts, centre, radius)
        if got is not None and (best is None or got[2] < best[2]):
            best = got
    if best is None:
        return xy, 0, 0
    centre, radius, scatter, outer, d = best
    inner = d < radius - NEAR * max(scatter, 1.0)
    if not inner.any() or outer.mean() < MIN_SHARE or scatter * THINNER >= one[2]:
        return xy, 0, 0
    t = np.arange(len(pts))
    phi = np.unwrap(np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0]))
    along = np.interp(t, t[outer], phi[outer])
    step = float(np.median(np.abs(np.diff(phi[outer])))) if outer.sum() > 2 else 0.0
    follows = np.abs(np.angle(np.exp(1j * (phi - along)))) <= FOLLOW * max(step, 1e-3)
    if (inner & follows).sum() < HALF * inner.sum():
        return xy, 0, 0
    # the rest (a point by the pivot, where the string's top barely moves) say nothing of the
    # direction: read from the arc's neighbours in time, as strays are (tracking.mend)
    strays = inner & ~follows
    if _longest_run(strays) > STRAY_RUN:
        # a long gap read across by a straight line cuts the curve of the swing (0.08 rad at a turn
        # 15 frames long): no reading at all is better than that one
        return xy, 0, 0
    inner &= follows
    out = xy.copy()
    rows = np.flatnonzero(ok)
    out[rows[inner]] = centre + (pts[inner] - centre) * (radius / np.maximum(d[inner], 1e-9))[:, None]
    out[rows[strays]] = centre + radius * np.stack([np.cos(along[strays]), np.sin(along[strays])], axis=1)
    return out, int(inner.sum()), int(strays.sum())


def _outer_arc(pts: np.ndarray, centre: np.ndarray, radius: float | None):
    """The arc the points lie on farthest from `centre` (the larger group of their distances, or
    those within NEAR pixels of `radius`), fitted alone and its points taken again three times:
    (centre, radius, scatter, on the arc (T,), distances (T,)), or None."""
    d = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1])
    outer = _two_means(d) if radius is None else np.abs(d - radius) <= NEAR
    if outer is None:
        return None
    for _ in range(3):
        if outer.sum() < max(MIN_SHARE * len(pts), 5):
            return None
        arc = _geometric(pts[outer])
        if arc is None:
            return None
        centre, radius, scatter, _ = arc
        d = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1])
        outer = np.abs(d - radius) <= NEAR * max(scatter, 1.0)
    return centre, radius, scatter, outer, d


TRIES = 200  # circles through three points tried by _consensus_circle


def _consensus_circle(pts: np.ndarray) -> tuple[np.ndarray, float | None]:
    """The circle through three of the points (TRIES seeded draws) that the most points lie within
    NEAR pixels of: (centre, radius); (their mean, None) where every draw lies on a line."""
    rng = np.random.default_rng(0)
    a, b, c = (pts[rng.integers(len(pts), size=TRIES)] for _ in range(3))
    # the circumcentre of each triple
    den = 2 * (a[:, 0] * (b[:, 1] - c[:, 1]) + b[:, 0] * (c[:, 1] - a[:, 1]) + c[:, 0] * (a[:, 1] - b[:, 1]))
    ok = np.abs(den) > 1e-9
    a2, b2, c2 = (v[:, 0] ** 2 + v[:, 1] ** 2 for v in (a, b, c))
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = (a2 * (b[:, 1] - c[:, 1]) + b2 * (c[:, 1] - a[:, 1]) + c2 * (a[:, 1] - b[:, 1])) / den
        uy = (a2 * (c[:, 0] - b[:, 0]) + b2 * (a[:, 0] - c[:, 0]) + c2 * (b[:, 0] - a[:, 0])) / den
    centres = np.stack([ux, uy], axis=1)[ok]
    radii = np.hypot(*(a[ok] - centres).T)
    if not len(centres):
        return pts.mean(axis=0), None
    d = np.hypot(pts[None, :, 0] - centres[:, :1], pts[None, :, 1] - centres[:, 1:])
    i = int(np.argmax((np.abs(d - radii[:, None]) <= NEAR).sum(axis=1)))
    return centres[i], float(radii[i])


GRID = 25  # candidate centres per side of the square the smoothest direction is looked for in


def _smoothest_centre(pts: np.ndarray) -> np.ndarray:
    """The point about which the direction of pts (T, 2, in time order) runs most smoothly in
    time: the median of its second differences over its range, on a grid three times the path's
    extent about its middle (a pivot above the frame included)."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    half = 1.5 * max(float((hi - lo).max()), 1.0)
    mid = (lo + hi) / 2
    g = np.linspace(-half, half, GRID)
    cx, cy = np.meshgrid(mid[0] + g, mid[1] + g)
    centres = np.stack([cx.ravel(), cy.ravel()], axis=1)
    phi = np.unwrap(np.arctan2(pts[None, :, 1] - centres[:, 1:2], pts[None, :, 0] - centres[:, :1]), axis=1)
    rough = np.median(np.abs(phi[:, 2:] - 2 * phi[:, 1:-1] + phi[:, :-2]), axis=1)
    spread = np.percentile(phi, 95, axis=1) - np.percentile(phi, 5, axis=1)
    return centres[int(np.argmin(rough / np.maximum(spread, 1e-12)))]


def _two_means(d: np.ndarray) -> np.ndarray | None:
    """The larger of two groups of the distances d (two means, started at their median); None
    where one group is empty."""
    outer = d > np.median(d)
    for _ in range(20):
        if outer.all() or not outer.any():
            return None
        moved = d > (d[outer].mean() + d[~outer].mean()) / 2
        if np.array_equal(moved, outer):
            break
        outer = moved
    return None if outer.all() or not outer.any() else outer


def _longest_run(mask: np.ndarray) -> int:
    """The length of the longest run of True in mask."""
    best = run = 0
    for v in mask:
        run = run + 1 if v else 0
        best = max(best, run)
    return best
