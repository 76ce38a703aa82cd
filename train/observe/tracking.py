"""Where something is in each frame: the centroid of what differs most from the static scene,
and the clean-up of a path that runs one way (the position observation and the auto choice).

The heat map is what differs from the clip's median frame (the static scene) by more than three
times the noise (median absolute deviation) and by more than CORE of the frame's largest
difference, cut to its strongest connected region; its centroid moves with the object, exactly
for a rigid object in view on a static background, whatever its shape, colour or contrast.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

ONE_WAY = 0.9  # |rank correlation| with time from which a path counts as running one way
# a path that is not one way as a whole (a hand that holds a ball, a bounce, a track that takes up
# something else before and after) still runs one way where one run of it covers RUN of its travel
# and no run the other way covers more than BACK of it (the real drop's bounce: 0.18)
RUN = 0.8
BACK = 1 / 3
CORE = 0.7
MEND_SPAN = 21  # frames around each frame whose running median a one-way path is checked against
MEND_SIGMAS = 6.0
MEND_PIXELS = 1.0
EDGE_MAX = 0.25  # a run of mended frames at an end of the fitted frames, up to this share of them, is not counted
EDGE_GAP = 3  # ... its frames apart by at most this many
MENDED_MAX = 0.1  # a larger share of mended frames is a finding: the centroid is not the object's


@torch.no_grad()
def centroids(frames: torch.Tensor, fit_frames: int | None = None) -> tuple[torch.Tensor, float, int, torch.Tensor]:
    """(T, 2) image coordinates (x, y) of the centroid of each frame's change from the static
    scene, the mean number of pixels that carry it, how many frames show no change (their
    centroid is the previous frame's), and each frame's largest change (T,).

    The static scene is first the median frame of the first fit_frames; an object that slows
    down (a decay, the end of a slide) sits in that median where it lingers, and its ghost there
    pulls the centroid. So a second pass rebuilds each pixel's background from the frames in
    which the first pass put the object farther away than twice its size, and measures again.
    """
    gray = frames.double().mean(dim=1)  # (T, H, W)
    n_fit = gray.shape[0] if fit_frames is None else int(fit_frames)
    background = gray[:n_fit].median(dim=0).values
    xy, heat = _centroids(gray, background)
    size = float((heat > 0).sum(dim=(1, 2)).double().mean()) ** 0.5
    h, w = gray.shape[1:]
    ys, xs = torch.meshgrid(torch.arange(h, dtype=gray.dtype, device=gray.device),
                            torch.arange(w, dtype=gray.dtype, device=gray.device), indexing="ij")
    far = ((xs[None] - xy[:n_fit, 0, None, None]) ** 2 + (ys[None] - xy[:n_fit, 1, None, None]) ** 2) > (2 * size + 2) ** 2
    count = far.sum(dim=0)
    clean = (gray[:n_fit] * far).sum(dim=0) / count.clamp_min(1)
    background = torch.where(count >= max(3, n_fit // 10), clean, background)
    xy, heat = _centroids(gray, background)
    mass = heat.sum(dim=(1, 2))
    seen = mass > 0
    for t in range(1, len(xy)):  # a frame with no change keeps the last position seen
        if not seen[t]:
            xy[t] = xy[t - 1]
    pixels = float((heat > 0).sum(dim=(1, 2)).double().mean())
    return xy, pixels, int((~seen).sum()), heat.flatten(1).max(dim=1).values


def mended_caution(mended: Sequence[int], first: int, last: int) -> str | None:
    """The caution for the frames read from their neighbours (mended: frame indices) among the
    frames fitted, [first, last), where they are more than MENDED_MAX of them; None otherwise.
    Frames outside are not the fit's (a hand before the release, a bounce after the fall), and
    neither is a run of them at an end of the fitted frames, up to EDGE_MAX of them: that is the
    object meeting something where its motion starts or stops (a ball one blob with the hand that
    lets it go), read from the frames next to it; whether the rest follow one trajectory is the
    consistency checks' to say."""
    inside = sorted(i for i in set(mended) if first <= i < last)
    span = max(last - first, 1)
    edge = _edge_run(inside, first, 1) + _edge_run(inside[::-1], last - 1, -1)
    counted = len(inside) - edge if edge <= EDGE_MAX * span else len(inside)
    if counted <= MENDED_MAX * span:
        return None
    return (f"{counted} of {span} fitted frames had a centroid off the path of their neighbours and were read from "
            "them: something else changes in the view as much as the object; give --roi around it")


def _edge_run(frames: Sequence[int], end: int, way: int) -> int:
    """How many of the mended frames (sorted from `end` inward, way +1 or -1) form a run at that
    end of the fitted frames: the first within EDGE_GAP frames of it, each next within EDGE_GAP."""
    count, at = 0, end - way
    for i in frames:
        if abs(i - at) > EDGE_GAP:
            break
        count, at = count + 1, i
    return count


def mend_one_way(path: torch.Tensor, n_fit: int | None = None) -> tuple[torch.Tensor, int]:
    """A path that runs one way (runs_one_way over the first n_fit frames) with the frames that
    leave it read from their neighbours, and how many those are.

    A one-way path is its own running median (the median of a monotone run is its middle), so
    a frame far from the running median of the MEND_SPAN frames around it is not the object:
    where the change from the static scene is a boundary (a water level), it vanishes as the
    level passes its median place, and the centroid of whatever else changes then (the jet under
    the bottle) is taken for a few frames. Far means more than MEND_SIGMAS times the residuals'
    robust spread and more than MEND_PIXELS. The ends are extended by point reflection, which
    keeps a steady run steady. A path that turns back (an oscillation) is left as it is."""
    n = path.shape[0]
    n_fit = n if n_fit is None else int(n_fit)
    if n_fit < 8:
        return path, 0
    if not runs_one_way(path[:n_fit]):
        return path, 0
    x = path.double().cpu().numpy()
    half = max(2, min(MEND_SPAN // 2, n // 4))
    mended, off = x, np.zeros(n, dtype=bool)
    for _ in range(2):  # the second round against the mended path: the first's median leans towards a run of strays
        padded = np.concatenate([2 * mended[0] - mended[half:0:-1], mended,
                                 2 * mended[-1] - mended[-2:-half - 2:-1]])
        residual = x - np.median(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1), axis=1)
        spread = float(noise_level(torch.from_numpy(np.abs(residual))))
        off = np.abs(residual) > max(MEND_SIGMAS * spread, MEND_PIXELS)
        if not off.any() or off.all():
            return path, 0
        good = np.flatnonzero(~off)
        mended = x.copy()
        mended[off] = np.interp(np.flatnonzero(off), good, x[good])
    return torch.as_tensor(mended, dtype=path.dtype, device=path.device), int(off.sum())


def mend(path: torch.Tensor, n_fit: int | None = None) -> tuple[torch.Tensor, int]:
    """A path (T,) with the frames that leave it read from their neighbours, and how many those
    are: against the running median where it runs one way (mend_one_way), else against a local
    parabola (mend_strays: an oscillation)."""
    n_fit = path.shape[0] if n_fit is None else int(n_fit)
    if n_fit >= 8 and runs_one_way(path[:n_fit]):
        return mend_one_way(path, n_fit)
    mended, count = mend_strays(path.double().cpu().numpy(), n_fit)
    return torch.as_tensor(mended, dtype=path.dtype, device=path.device), count


def one_way(path: torch.Tensor) -> float:
    """How one way a path (T,) runs in time: the absolute rank correlation of its values with
    their frame numbers (1: monotone; about 0: back and forth)."""
    ranks = torch.argsort(torch.argsort(path)).double()
    t = torch.arange(len(ranks), dtype=torch.float64, device=ranks.device)
    return abs(float(torch.corrcoef(torch.stack([ranks, t]))[0, 1]))


def runs_one_way(path: torch.Tensor) -> bool:
    """A path (T,) runs one way: its rank correlation with time is at least ONE_WAY, or one run of
    it covers RUN of its travel and no run the other way more than BACK (one_way_run)."""
    return one_way(path) >= ONE_WAY or covers_one_way(one_way_run(path.double().cpu().numpy()))


def covers_one_way(run: tuple[float, float]) -> bool:
    """One run covers RUN of the travel one way and no run the other way more than BACK (the
    shares one_way_run gives)."""
    return run[0] >= RUN and run[1] <= BACK


def one_way_run(path: np.ndarray) -> tuple[float, float]:
    """The shares of a path's (T,) travel its longest one-way run covers and its longest run the
    other way does (fitode.train.stretch.one_way_runs)."""
    from ..stretch import one_way_runs
    first, other = sorted((share for _, _, share in one_way_runs(path).values()), reverse=True)
    return first, other


# a path runs along a straight line where its scatter across its line of motion is under STRAIGHT
# of its travel along it (a generated cart that bounces on its track: 0.0004; a spring that sways
# while it bounces, or a throw's parabola, is far wider)
STRAIGHT = 0.03


def line_of_motion(xy: torch.Tensor, n_fit: int | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """The direction (2,) along which the centroids of the first n_fit frames spread most, and
    every centroid's signed distance along it from their mean, (T,)."""
    n_fit = xy.shape[0] if n_fit is None else n_fit
    centred = xy - xy[:n_fit].mean(dim=0)
    direction = torch.linalg.svd(centred[:n_fit], full_matrices=False).Vh[0]
    return direction, centred @ direction


def straightness(xy: torch.Tensor) -> float:
    """A path's (T, 2) scatter across its line of motion (a standard deviation) over its travel
    along it: under STRAIGHT, it runs along a straight line (inf for a path that does not move)."""
    xy = xy.double()
    direction, along = line_of_motion(xy)
    across = (xy - xy.mean(dim=0)) @ torch.stack([-direction[1], direction[0]])
    travel = float(along.max() - along.min())
    return float(across.std()) / travel if travel > 0 else float("inf")


def noise_level(diff: torch.Tensor) -> torch.Tensor:
    """The noise level of differences from the static scene: their median absolute value, scaled
    to a standard deviation (most pixels of most frames show only noise)."""
    return 1.4826 * diff.flatten().median() + 1e-12


def _centroids(gray: torch.Tensor, background: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    diff = (gray - background).abs()
    noise = noise_level(diff)
    # only each frame's strongest change: the object, not a hand that moves at the edge, a
    # shadow or the camera's exposure drifting over the whole wall
    floor = torch.maximum(3 * noise, CORE * diff.flatten(1).max(dim=1).values)[:, None, None]
    heat = _strongest_region(torch.where(diff > floor, diff, torch.zeros_like(diff)))
    mass = heat.sum(dim=(1, 2)).clamp_min(1e-12)
    h, w = gray.shape[1:]
    ys = torch.arange(h, dtype=heat.dtype, device=heat.device)
    xs = torch.arange(w, dtype=heat.dtype, device=heat.device)
    cx = (heat.sum(dim=1) * xs).sum(dim=1) / mass
    cy = (heat.sum(dim=2) * ys).sum(dim=1) / mass
    return torch.stack([cx, cy], dim=1), heat


def _strongest_region(heat: torch.Tensor) -> torch.Tensor:
    """Each frame's heat (T, H, W) cut to its connected region of largest total change (pixels
    one apart count as connected): a hand that pulls back at the frame's edge while a fading,
    motion-blurred ball crosses the middle passes the threshold too, and the centroid of both
    lies between them, where nothing is."""
    import cv2

    kept = heat.clone()
    near = np.ones((3, 3), np.uint8)
    for t, frame in enumerate(heat.cpu().numpy()):
        mask = cv2.dilate((frame > 0).astype(np.uint8), near)
        n, labels = cv2.connectedComponents(mask, connectivity=8)
        if n <= 2:  # one region, or none
            continue
        mass = np.bincount(labels.ravel(), weights=frame.ravel(), minlength=n)
        mass[0] = 0.0
        kept[t] = torch.where(torch.from_numpy(labels == int(np.argmax(mass))).to(heat.device), heat[t], 0.0)
    return kept


STRAY_SPAN = 2  # neighbours on each side whose local parabola a frame of a turning path is checked against
ROUNDS = 5


def mend_strays(xy: np.ndarray, n_fit: int | None = None) -> tuple[np.ndarray, int]:
    """A path (T,) or (T, k) of any shape (an oscillation too) with the frames that leave it
    read from their neighbours, and how many those are.

    Each frame is compared with the parabola in time through the 2 STRAY_SPAN frames around it
    (itself left out; at the ends, the nearest such frames, its miss then scaled down by the
    larger noise of an extrapolation), fitted per coordinate: a swing is smooth over a few frames
    and a bounce lies on a line with the frames on one side of it, a centroid that jumped to
    something else for a frame or two does neither. Far means more than MEND_SIGMAS times the misses' robust spread over the first
    n_fit frames and more than MEND_PIXELS. A stray also pulls its neighbours' parabolas, so the
    first round takes only the frames that miss most among their neighbours, and later rounds
    check every frame against the path so mended (up to ROUNDS, until nothing changes)."""
    x = np.asarray(xy, dtype=np.float64)
    x = x[:, None] if x.ndim == 1 else x
    n, h = len(x), STRAY_SPAN
    n_fit = n if n_fit is None else int(n_fit)
    if n < 2 * h + 3 or n_fit < 2 * h + 3:
        return np.asarray(xy), 0
    # frame t is predicted from the window of 2h + 1 frames starting at start[t], t left out: one
    # linear filter per place of t in its window (least squares, evaluated at t)
    start = np.clip(np.arange(n) - h, 0, n - 2 * h - 1)
    place = np.arange(n) - start
    offsets = np.arange(2 * h + 1, dtype=np.float64)
    filters = np.zeros((2 * h + 1, 2 * h + 1))
    for p in range(2 * h + 1):
        others = np.delete(offsets, p) - p
        design = np.column_stack([np.ones_like(others), others, others ** 2])
        filters[p] = np.insert(np.linalg.pinv(design)[0], p, 0.0)
    index = start[:, None] + np.arange(2 * h + 1)[None, :]  # (T, 2h+1)
    # a miss in units of the noise it would have: a frame at an end is extrapolated, with a larger one
    gain = np.sqrt(1 + (filters ** 2).sum(axis=1))[place]
    mended, off, first = x, np.zeros(n, dtype=bool), None
    threshold = None
    # a bounce is a kink, not a stray: every frame near it lies on the line through the two frames
    # before it (and so does the frame before it), or on the parabola through the three before it
    # (a fall filmed at 30 fps bends by g dt^2, several pixels, from frame to frame), or on either
    # through those after it, where a centroid that jumped to something else for a frame or a few
    # lies on none (a ball's bounces were read from their neighbours)
    left, right = np.full(n, np.inf), np.full(n, np.inf)
    left[2:] = np.linalg.norm(x[2:] - (2 * x[1:-1] - x[:-2]), axis=1) / np.sqrt(6.0)  # a line's extrapolation
    right[:-2] = np.linalg.norm(x[:-2] - (2 * x[1:-1] - x[2:]), axis=1) / np.sqrt(6.0)
    left[3:] = np.minimum(left[3:], np.linalg.norm(x[3:] - (3 * x[2:-1] - 3 * x[1:-2] + x[:-3]), axis=1) / np.sqrt(20.0))
    right[:-3] = np.minimum(right[:-3], np.linalg.norm(x[:-3] - (3 * x[1:-2] - 3 * x[2:-1] + x[3:]), axis=1) / np.sqrt(20.0))
    for _ in range(ROUNDS):
        predicted = np.einsum("tw,twk->tk", filters[place], mended[index])
        miss = np.linalg.norm(x - predicted, axis=1) / gain
        if threshold is None:
            threshold = max(MEND_SIGMAS * 1.4826 * float(np.median(miss[:n_fit])), MEND_PIXELS / gain.min())
        line = np.zeros(n, dtype=bool)
        line[1:] |= (left[1:] <= threshold) & (left[:-1] <= threshold)
        line[:-1] |= (right[:-1] <= threshold) & (right[1:] <= threshold)
        far = (miss > threshold) & ~line
        if first is None:
            # (among the far frames: a frame that lies on its side's curve is no candidate, however a
            # stray next to it pulls its parabola)
            padded = np.concatenate([np.zeros(h), miss * far, np.zeros(h)])
            first = far & (miss >= np.lib.stride_tricks.sliding_window_view(padded, 2 * h + 1).max(axis=1))
            now = first
        else:  # a neighbour a stray's parabola pulled is let go once the stray is mended
            now = first | far
        if np.array_equal(now, off):
            break
        off = now
        if off.sum() > n // 2:
            return np.asarray(xy), 0
        good = np.flatnonzero(~off)
        mended = x.copy()
        for j in range(x.shape[1]):
            mended[off, j] = np.interp(np.flatnonzero(off), good, x[good, j])
    out = mended[:, 0] if np.asarray(xy).ndim == 1 else mended
    return out, int(off.sum())
