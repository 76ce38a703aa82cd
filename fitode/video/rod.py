"""A swing read by its string: the direction of a thin line that turns about one point.

A small pale ball on a long dark string changes the frames less than its string does: the change
detector's path then goes between the ball and pieces of the string from frame to frame, and the
object tracker's template, cut with the string in it, turns with the swing and loses the ball
(generated pendulums of coverage seeds 0 and 1: the tracker placed the ball in 1-62% of the
frames, and the free encoder took over). The string itself is easy to read: in each frame, the
pixels that differ from the static scene in the string's sense (darker, for a dark string) lie on
a line, and every frame's line passes through the pivot. The angle of that line is the swing's.

read_rod gives the track of the line's far end (where the string meets what hangs from it): the
pivot (the point all the frames' lines pass closest to, least squares) plus the string's length
along each frame's direction. That point moves on an exact circle about the pivot, so the angle
observation reads the line's angle, and a position observation reads where the bob hangs.

Where the change is no thin line in most frames (a ball, a cart, a can), where the lines do not
meet at one point (a rod that slides, a swing seen at a slant), or where the line barely turns, it
is no swing by its string: None, and the reader keeps what it had.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

SIGMAS = 4.0      # a pixel is on the line where it differs from the static scene by this many times the noise
MIN_PIXELS = 12   # ... in the line's sense, at least this many of them in a frame
SPECKLE = 4       # connected pieces of fewer pixels are noise, not the line
THIN = 0.08       # the line's RMS width over its length, at most
MIN_LENGTH = 12.0  # pixels: the shortest line read
LINE_SHARE = 0.8  # the frames in which the change must be such a line
MEETS = 1.5       # pixels: the lines' RMS distance from the point they meet at, at most
OFF_PIVOT = 3.0   # ... a frame whose line passes farther than this many times that from it is not read
MIN_TRAVEL = 3.0  # pixels: how far the line's far end must move, at least (a line that barely turns is no swing)
NEAR_SHARE = 0.25  # the second reading leaves out the line's part within this share of its length of the pivot,
NEAR_PIXELS = 4.0  # ... or where the string sweeps fewer than this many pixels, whichever is farther,
END_SHARE = 0.1   # ... and the part within this share of its length, and END_PIXELS, of its far end
END_PIXELS = 3.0
FIT_ROUNDS = 3    # rounds of the robust line fit (pixels farther than 3 RMS widths, and 2 px, set aside)


def read_rod(stack: np.ndarray, background: np.ndarray, noise: float) -> tuple[np.ndarray, str] | None:
    """(T, 2) the place of the far end of a thin line (a pendulum's string or rod) that turns about
    one point in gray frames (T, H, W) uint8, NaN where a frame's line is not read, and one line on
    how; None where the frames show no such line (see the module docstring). background: the
    static scene (H, W); noise: one pixel's standard deviation about it."""
    base = background.astype(np.int16)
    floor = SIGMAS * max(float(noise), 0.5)
    sign = _sense(stack, base, floor)
    first = _lines(stack, base, sign, floor, None)
    if first is None:
        return None
    pivot, miss, direction, ok, far = first
    length = float(np.median(far[ok]))
    # read again between the pivot's neighbourhood and what hangs at the end: near the pivot the
    # string sweeps less than its own width, so the static scene holds it and the frame's change
    # there leans its line towards the middle (a generated swing of 7 degrees read 0.981 of its
    # angle); the bob and its shadow on the wall pull the far end sideways (0.4 degrees)
    swing = float(np.ptp(np.arctan2(direction[ok, 0], direction[ok, 1])))
    near = max(NEAR_SHARE * length, NEAR_PIXELS / max(swing, 1e-3))
    h, w = stack.shape[1:]
    yy, xx = np.mgrid[0:h, 0:w]
    r = np.hypot(xx - pivot[0], yy - pivot[1])
    band = (r >= near) & (r <= length - END_SHARE * length - END_PIXELS)
    second = _lines(stack, base, sign, floor, band) if band.any() else None
    if second is not None:
        pivot, miss, direction, ok, _ = second
    xy = np.where(ok[:, None], pivot[None] + length * direction, np.nan)
    span = np.ptp(xy[ok], axis=0)
    if float(span.max()) < MIN_TRAVEL:
        return None
    how = (f"the direction of a thin line turning about ({pivot[0]:.1f}, {pivot[1]:.1f}) (a swing's string: its lines "
           f"meet there within {miss:.2g} px), read {length:.0f} px from it, where the string ends; "
           f"{int((~ok).sum())} of {len(ok)} frames unread")
    return xy, how


def _lines(stack: np.ndarray, base: np.ndarray, sign: int, floor: float, band: np.ndarray | None):
    """Each frame's line (its change from the static scene base in the sense sign, inside band
    where given) and the point they meet at: (pivot, the lines' RMS distance from it, (T, 2)
    directions away from it, (T,) which frames are read, (T,) the distance of each line's far end
    from it), or None where the lines are too few or do not meet at one point."""
    lines, missing = [], 0
    allowed = len(stack) - max(8, LINE_SHARE * len(stack))
    for frame in stack:  # a frame at a time: the whole clip's change in int16 would double its memory
        change = sign * (frame.astype(np.int16) - base)
        lines.append(_line(change if band is None else np.where(band, change, 0), floor))
        missing += lines[-1] is None
        if missing > allowed:
            return None  # no thin line in too many frames: a ball, a cart (cheap to tell)
    ok = np.array([ln is not None for ln in lines])
    centre = np.array([ln[0] if ln is not None else (np.nan, np.nan) for ln in lines])
    direction = np.array([ln[1] if ln is not None else (np.nan, np.nan) for ln in lines])
    pivot, miss = _meeting(centre[ok], direction[ok])
    if pivot is None or not miss <= MEETS:
        return None
    normal = np.stack([-direction[:, 1], direction[:, 0]], axis=1)
    off = np.abs(np.einsum("ij,ij->i", normal, pivot[None] - centre))
    ok &= off <= max(OFF_PIVOT * miss, 1.0)
    # each direction pointing from the pivot to the line's middle: along the string, away from it
    flip = np.einsum("ij,ij->i", centre - pivot[None], direction) < 0
    direction[flip] *= -1.0
    ends = np.array([ln[2] if ln is not None else (np.nan, np.nan) for ln in lines])
    far = np.where(flip, -ends[:, 0], ends[:, 1]) + np.einsum("ij,ij->i", centre - pivot[None], direction)
    return pivot, miss, direction, ok, far


def _sense(stack: np.ndarray, base: np.ndarray, floor: float) -> int:
    """+1 where the moving thing is lighter than the static scene in more pixels, -1 where darker."""
    lighter = darker = 0
    for frame in stack[::max(1, len(stack) // 16)]:
        d = frame.astype(np.int16) - base
        lighter, darker = lighter + int((d > floor).sum()), darker + int((d < -floor).sum())
    return 1 if lighter > darker else -1


def _line(change: np.ndarray, floor: float) -> tuple[np.ndarray, np.ndarray, tuple[float, float]] | None:
    """One frame's line through the pixels whose change (in the line's sense) exceeds floor:
    (a point on it (x, y), its unit direction, where its ends lie from that point along the
    direction (the 1st and 99th percentiles)) or None where they make no thin line. Weighted by
    their change; robust to a few pixels beside it (the bob, a speck of noise)."""
    mask = (change > floor).astype(np.uint8)
    if int(mask.sum()) < MIN_PIXELS:
        return None
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    keep = np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= SPECKLE) + 1
    if not len(keep):
        return None
    ys, xs = np.nonzero(np.isin(labels, keep))
    if len(xs) < MIN_PIXELS:
        return None
    p = np.column_stack([xs, ys]).astype(np.float64)
    w = change[ys, xs].astype(np.float64) - floor
    use = np.ones(len(p), bool)
    for _ in range(FIT_ROUNDS):
        if use.sum() < MIN_PIXELS:
            return None
        c = np.average(p[use], axis=0, weights=w[use])
        q = p[use] - c
        cov = (q * w[use, None]).T @ q / w[use].sum()
        vals, vecs = np.linalg.eigh(cov)
        d = vecs[:, 1]
        across = (p - c) @ np.array([-d[1], d[0]])
        width = math.sqrt(max(float(vals[0]), 0.0))
        use = np.abs(across) <= max(3.0 * width, 2.0)
    along = (p[use] - c) @ d
    # its ends where it is as strong as the line itself: a shadow on the wall past the bob darkens
    # it less (a soft shadow at a third of the string's contrast read the string 4% long)
    strong = w[use] >= 0.5 * float(np.median(w[use]))
    lo, hi = np.percentile(along[strong], [1, 99])
    length = float(hi - lo)
    if length < MIN_LENGTH or width > THIN * length:
        return None
    return c, d, (float(lo), float(hi))


def _meeting(centre: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray | None, float]:
    """The point closest to all the lines (each through centre along direction; least squares) and
    their RMS distance from it; None where they are too near parallel to meet."""
    normal = np.stack([-direction[:, 1], direction[:, 0]], axis=1)
    a = normal.T @ normal
    b = normal.T @ np.einsum("ij,ij->i", normal, centre)
    vals = np.linalg.eigvalsh(a)
    # lines that turn by less than a degree or so meet anywhere along them
    if not vals[0] > 1e-4 * vals[1]:
        return None, math.inf
    pivot = np.linalg.solve(a, b)
    miss = float(np.sqrt(np.mean(np.einsum("ij,ij->i", normal, pivot[None] - centre) ** 2)))
    return pivot, miss
