"""Where a water line is, where the change from the static scene is a band of water rather than
an object.

As a tank drains, what differs from the static scene (the clip's median frame) is the band of
rows between the line now and its place in the median frame: one end of the band stays at that
place, the other is the line. The band's centroid moves half as far as the line does (on the
shared draining bottle, the reader's centroid against the colour tracker's water top of
bench/realclips.py: slope 0.50), and vanishes where the line passes its median place. So where the change detector's path is such a band, the
reading is the band's moving end instead.

The tank's columns (those around the detector's path whose change stands above the noise) are
averaged per row, so that each frame is a row profile; its difference from the median profile
is the band. In each frame the band is the run of rows that change by at least half the frame's
largest change; the end that lies at the same row in most frames (within ANCHOR rows) is the
line's median place, and the other end is the line. Its row is read to a fraction of a pixel as
the outermost place where the change crosses half the band's step (its plateau just inside the
end): a blurred step crosses half its height at the edge itself, and a meniscus or the far rim
of the surface, seen from a little above, belongs to the water when it changes by that much.

A frame whose band shows no end away from the median place (the line at it, or something else
changing more) is read from the nearest frame read so by the shift of the tank's rows between
them.
"""
from __future__ import annotations

import numpy as np

ANCHOR = 2.0      # rows: a band's end this close to the median place is at it
ANCHORED = 0.8    # the share of the frames with a band whose band reaches the median place
TRAVEL = 5.0      # the line's travel must be at least this many times ANCHOR (else no line moves)
BAND = 0.5        # a frame's band: the rows changing by at least this share of its largest change
NOISE = 6.0       # ... and by this many times the profile's noise
GAP = 2           # rows below the threshold a band may bridge (a graduation mark, a highlight)
INSIDE = (2, 8)   # the rows inside the moving end whose change is the band's step (its plateau)
QUIET = 3         # rows under half the step that end the band outward
COLUMNS = 0.5     # the tank's columns: those around the path changing at least this share of its column
STEADY = 10.0     # a line moves steadily: no step between frames read beyond this many times the median step
#                   (and twice ANCHOR)


def read_line(stack: np.ndarray, path: np.ndarray, sample: np.ndarray, background: np.ndarray,
              noise: float) -> tuple[np.ndarray, str] | None:
    """(T, 2) the water line in gray frames (T, H, W) uint8, x the middle of the tank's columns
    and y the line's row (sub-pixel, NaN where unread), and one line on how; None where the
    change detector's path (T, 2) is no such band (an object, a lamp, a band whose ends both
    move). sample: the frames the static scene (background, (H, W)) is the median of; noise: the
    frames' noise about it (one pixel's standard deviation)."""
    seen = np.isfinite(path[:, 0])
    if seen.sum() < 8:
        return None
    spread = np.subtract(*np.percentile(path[seen], [95, 5], axis=0))
    if spread[1] <= spread[0]:
        return None  # a band of water grows and shrinks up and down: a cart rolling across is no level
    columns = _columns(stack[sample], background, path, noise)
    if columns is None:
        return None
    left, right = columns
    profile = stack[:, :, left:right + 1].mean(axis=2, dtype=np.float64)
    change = profile - np.median(profile, axis=0)
    floor = 1.4826 * float(np.median(np.abs(change))) + noise / np.sqrt(right - left + 1)
    runs = [_band(row, floor) for row in change]
    ends = np.array([(r[0], r[-1]) if r is not None else (np.nan, np.nan) for r in runs], dtype=np.float64)
    banded = np.isfinite(ends[:, 0])
    if banded.sum() < 8:
        return None
    anchor = _anchor(ends[banded].ravel())
    near = np.abs(ends - anchor) <= ANCHOR
    reaches = banded & near.any(axis=1)
    if reaches.sum() < ANCHORED * banded.sum():
        return None
    # the moving end: the one away from the median place (a band within ANCHOR of it has none)
    moving = reaches & ~near.all(axis=1)
    end = np.where(near[:, 0], ends[:, 1], ends[:, 0])
    if not moving.any() or np.ptp(end[moving]) < TRAVEL * ANCHOR:
        return None
    rows, step = _edges(change, runs, end, moving)
    edged = int(np.isfinite(rows).sum())
    rows = _near_anchor(change, rows, step, anchor)
    steps = np.abs(np.diff(rows[np.isfinite(rows)]))
    if len(steps) and steps.max() > STEADY * float(np.median(steps)) + 2 * ANCHOR:
        return None  # a line that jumps between edges (a generated slow drain's read 40, 57, then 44) is none
    # the change the detector followed is this band: its centroid lies between the line and the
    # line's median place (a frame or a few where the band vanishes take something else)
    both = np.isfinite(rows) & seen
    margin = 2 * ANCHOR + QUIET
    y = path[both, 1]
    inside = (y >= np.minimum(rows[both], anchor) - margin) & (y <= np.maximum(rows[both], anchor) + margin)
    if both.sum() < 8 or inside.mean() < ANCHORED:
        return None
    xy = np.stack([np.where(np.isfinite(rows), (left + right) / 2, np.nan), rows], axis=1)
    shifted = int(np.isfinite(rows).sum()) - edged
    note = ("the water line: the moving end of the band of change (whose centroid moves only part of the way)"
            + (f", and in {shifted} frame{'s' if shifted != 1 else ''} where the line passes its median place the "
               "shift of the rows from the nearest frame read" if shifted else ""))
    return xy, note


def _columns(frames: np.ndarray, background: np.ndarray, path: np.ndarray, noise: float) -> tuple[int, int] | None:
    """The tank's columns [left, right]: the run around the path's median column whose summed
    change from the background (beyond 4 times the noise, over frames spread through the clip) is
    at least COLUMNS of that column's."""
    heat = np.abs(frames.astype(np.int16) - background)
    per_column = np.where(heat > 4 * noise, heat, 0).sum(axis=(0, 1), dtype=np.float64)
    seed = int(np.clip(round(float(np.nanmedian(path[:, 0]))), 0, frames.shape[2] - 1))
    floor = COLUMNS * per_column[seed]
    if floor <= 0:
        return None
    left = right = seed
    while left > 0 and per_column[left - 1] >= floor:
        left -= 1
    while right < len(per_column) - 1 and per_column[right + 1] >= floor:
        right += 1
    return left, right


def _band(change: np.ndarray, floor: float) -> np.ndarray | None:
    """The rows of a frame's band (its run of strongest total change, gaps of GAP rows bridged),
    or None where no row changes beyond NOISE times the profile's noise floor."""
    size = np.abs(change)
    hot = np.flatnonzero(size > max(NOISE * floor, BAND * float(size.max())))
    if not len(hot):
        return None
    runs = np.split(hot, np.flatnonzero(np.diff(hot) > GAP + 1) + 1)
    return max(runs, key=lambda r: float(size[r[0]:r[-1] + 1].sum()))


def _anchor(ends: np.ndarray) -> float:
    """The row most bands end at (within ANCHOR): the line's place in the median frame."""
    rows = ends.astype(int)  # a band's ends are whole rows
    reach = int(ANCHOR)
    within = np.convolve(np.bincount(rows), np.ones(2 * reach + 1), mode="full")[reach:reach + rows.max() + 1]
    mode = int(np.argmax(within))
    return float(np.median(ends[np.abs(ends - mode) <= ANCHOR]))


def _edges(change: np.ndarray, runs: list, end: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T,) the moving end's row of each moving frame's band, sub-pixel (NaN elsewhere): the
    outermost place where the change crosses half the band's step; and (T,) that step, signed
    as the band's change (NaN where no frame shows it)."""
    t_all = np.arange(len(change))
    inward = np.zeros(len(change), dtype=int)
    sign = np.zeros(len(change))
    step = np.full(len(change), np.nan)
    for t in np.flatnonzero(moving):
        run = runs[t]
        inward[t] = 1 if end[t] == run[0] else -1
        sign[t] = np.sign(change[t, run].sum())
        inside = [int(end[t]) + inward[t] * j for j in range(*INSIDE) if run[0] <= int(end[t]) + inward[t] * j <= run[-1]]
        if len(inside) >= 3:
            step[t] = float(np.median(sign[t] * change[t, inside]))
    have = np.isfinite(step) & (step > 0)
    if not have.any():
        return np.full(len(change), np.nan), np.full(len(change), np.nan)
    # a band too thin to show its plateau (the line near its median place) takes its neighbours' step
    step = np.interp(t_all, t_all[have], step[have])
    rows = np.full(len(change), np.nan)
    for t in np.flatnonzero(moving):
        y = sign[t] * change[t] / step[t]
        out = -inward[t]
        last = r = int(end[t])
        quiet = 0
        while 0 <= r + out < len(y) and quiet < QUIET:
            r += out
            if y[r] >= 0.5:
                last, quiet = r, 0
            else:
                quiet += 1
        beyond = last + out
        if 0 <= beyond < len(y) and y[last] >= 0.5 > y[beyond]:
            rows[t] = last + out * (y[last] - 0.5) / (y[last] - y[beyond])
    return rows, sign * step


def _near_anchor(change: np.ndarray, rows: np.ndarray, step: np.ndarray, anchor: float) -> np.ndarray:
    """rows with each unread frame (its band too thin to show an end: the line at its median
    place) read from the nearest read frame: where the line moves by d rows, the rows it passes
    change by d times the step between air and water, so the sum of the profile's change between
    the two frames over the rows around both places, over that step, is the shift (exact for any
    shape of the line that moves with it)."""
    read = np.flatnonzero(np.isfinite(rows))
    out = rows.copy()
    if not len(read):
        return out
    for t in np.flatnonzero(~np.isfinite(rows)):
        near = int(read[np.argmin(np.abs(read - t))])
        # the step from above the line to below it: the band's change where the band lies above
        # the median place (water there now, air in the median frame), its opposite below it
        below = step[near] if rows[near] < anchor else -step[near]
        if not np.isfinite(below) or below == 0:
            continue
        top = int(np.floor(min(rows[near], anchor) - 2 * ANCHOR - QUIET))
        bottom = int(np.ceil(max(rows[near], anchor) + 2 * ANCHOR + QUIET))
        top, bottom = max(top, 0), min(bottom, change.shape[1] - 1)
        moved = float((change[t, top:bottom + 1] - change[near, top:bottom + 1]).sum())
        # a line moving down by d rows turns d rows from the water's value to the air's: -d * below
        out[t] = rows[near] - moved / below
    return out
