"""Where the moving object is in every frame, measured on the decoded frames before they are
shrunk: the reader's streaming pass hands each kept frame (inside --roi) to a TrackRecorder,
which keeps it in gray, and measures the whole clip once the pass is over.

The static scene is the per-pixel median of frames spread over the clip (follow.static_scene); an
object that lingers somewhere leaves a ghost there, so the background is rebuilt, pixel by pixel,
from the frames in which the first measure put the object farther away than twice its size (as
fitode.train.observe.tracking does on the shrunk frames). In each frame the object is the
connected region of largest total change among the pixels that differ from the background by
more than NOISE_SIGMAS times the noise and by more than CORE of the frame's largest change; the
centroid of that core and the ring of pixels around it, weighted by their change over the noise
floor, is sub-pixel (within a quarter of a pixel for a ball two pixels across). The core is first
opened (eroded, then dilated, by 3x3) where that leaves anything: a pendulum's string is thin and
often more contrasted than its bob, and pulls the centroid towards the pivot by a varying amount. The region is found on the change shrunk by LOCATE (cheap),
against the shrunk blocks' own spread (a codec's noise is correlated over its blocks; a small
object is looked for again at half the shrink), and measured at full resolution inside it.
Where the strongest change is a band of water between a water line and its place in the static
scene, the track is the line itself (fitode.video.waterline), not the band's centroid; where the
detector's path switches between things and the object tracker follows none, and the change is a
thin line turning about a point (a small bob on a long string), the track is that line's far end
read from its direction (fitode.video.rod).

The frames are kept at the source's resolution unless the clip would take more than TRACK_BYTES
so; then they are shrunk by the smallest whole factor that fits, and the track says so.
"""
from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

from fitode.train.observe.track import Track
from fitode.video.follow import SWITCHES, Followed, choose, static_scene, switches
from fitode.video.rod import read_rod
from fitode.video.waterline import read_line

TRACK_BYTES = 384 * 2 ** 20
NOISE_SIGMAS = 4.0
CORE = 0.5
LOCATE = 4  # the whole factor the change is shrunk by to find the object's region
MAX_OBJECTS = 3  # the strongest paths a track keeps for states that name their object
MIN_SIDE = 8  # frames given as an array narrower than this are not pictures to track
GHOST_FLOOR = 0.25  # gray levels: the least spread _ghost compares with (a rebuilt scene read off whole levels)


class TrackRecorder:
    """Collects the kept frames of one streaming pass in gray (crop: (x, y, w, h) in source
    pixels, the crop the training frames use; expected: about how many frames will come)."""

    def __init__(self, crop: tuple[int, int, int, int], expected: int | None, order: str = "BGR"):
        x, y, w, h = crop
        n = max(1, int(expected or 1024))
        self.factor = max(1, math.ceil(math.sqrt(w * h * n / TRACK_BYTES)))
        self.crop, self.order = crop, order
        self.frames: list[np.ndarray] = []
        self.dropped = False  # the clip ran far past its expected length: no track

    def add(self, frame: np.ndarray, unit: tuple[float, float], mask: np.ndarray | None) -> None:
        """One decoded source frame (H, W) or (H, W, C) of any dtype; unit: (scale, offset) to
        [0, 1]; mask: the crop's mask (1 keeps a pixel), or None."""
        if self.dropped:
            return
        x, y, w, h = self.crop
        f = frame[y:y + h, x:x + w]
        if f.ndim == 3 and f.shape[2] == 4:
            f = f[:, :, :3]
        if f.ndim == 3:
            f = cv2.cvtColor(np.ascontiguousarray(f), cv2.COLOR_BGR2GRAY if self.order == "BGR" else cv2.COLOR_RGB2GRAY)
        if f.dtype != np.uint8 or mask is not None:
            scale, offset = unit
            g = (f.astype(np.float32) - np.float32(offset)) * np.float32(255.0 * scale)
            if mask is not None:
                g *= mask
            f = np.clip(g + 0.5, 0, 255).astype(np.uint8)
        if self.factor > 1:
            k = self.factor
            f = cv2.resize(f[:h - h % k, :w - w % k], (w // k, h // k), interpolation=cv2.INTER_AREA)
        self.frames.append(f)
        if len(self.frames) * f.size > 2 * TRACK_BYTES:
            self.frames, self.dropped = [], True

    def finish(self, index: np.ndarray | None = None) -> Track | None:
        """The track of the collected frames index (the clip's frames after its stride and its
        frame times' repairs; None: all), in source pixels; None where too few frames came, or
        too many to keep."""
        if self.dropped or len(self.frames) < 3:
            return None
        index = np.arange(len(self.frames)) if index is None else np.asarray(index, dtype=int)
        if len(index) < 3 or index.min() < 0 or index.max() >= len(self.frames):
            return None
        stack = np.stack([self.frames[i] for i in index])
        self.frames = []
        paths, areas = measure_paths(stack, MAX_OBJECTS, per_frame=True)
        area = float(np.nanmean(areas)) if np.isfinite(areas).any() else 0.0
        xy, how, found, line = place(stack, paths, areas)
        if found is not None:  # the object's own size, not that of the change the detector followed
            area = found.area
        k = self.factor

        def source(p: np.ndarray) -> np.ndarray:
            return np.stack([self.crop[0] + (p[..., 0] + 0.5) * k - 0.5, self.crop[1] + (p[..., 1] + 0.5) * k - 0.5], axis=-1)

        where = "at the source's resolution" if k == 1 else f"on frames shrunk {k}x to stay within memory"
        # a template's size is in `how`; a water line has none
        size = "" if found is not None or line else f", {area * k * k:.0f} source pixels on average"
        note = f"{how}{size}, measured {where}"
        return Track(source(xy), float(area * k * k), k, note, objects(source(paths)), followed=found is not None,
                     line=line)


def track_array(frames: np.ndarray) -> Track | None:
    """The reader's track of frames given as an array (T, C, H, W) float (fitode.api.as_frames),
    their pixels the source's: the same measure a video's frames get as they are decoded, so that
    a clip and its frames passed as an array are read alike."""
    x = np.asarray(frames, dtype=np.float32)
    if x.ndim != 4 or x.shape[1] not in (1, 3) or min(x.shape[2:]) < MIN_SIDE:
        return None  # not pictures: measured columns or subspace coefficients given as frames
    lo, hi = float(x.min()), float(x.max())
    if not hi > lo:
        return None
    recorder = TrackRecorder((0, 0, x.shape[3], x.shape[2]), len(x), "RGB")
    for frame in x:
        recorder.add(frame[0] if frame.shape[0] == 1 else frame.transpose(1, 2, 0), (1.0 / (hi - lo), lo), None)
    return recorder.finish()


def place(stack: np.ndarray, paths: np.ndarray, areas: np.ndarray,
          found: Followed | None = None) -> tuple[np.ndarray, str, Followed | None, bool]:
    """The path the reader takes through gray frames (T, H, W) uint8 given the change detector's
    paths and its first path's area per frame (measure_paths): the object tracker's or the
    detector's (follow.choose), or, where the detector's path is the centroid of a band of water,
    the water line (waterline.read_line). Returns the path (T, 2), one line on why, the object
    tracker's result where its path was taken, and whether the path is a water line. found: the
    object tracker's result where the caller has it."""
    xy, how, found = choose(stack, paths, areas, found)
    if found is None:
        scene = static_scene(stack)
        line = read_line(stack, paths[0], *scene)
        if line is not None:
            return line[0], line[1], None, True
        if switches(paths[0], areas) >= SWITCHES:
            # neither follows one object: a thin string that changes the frames more than the small
            # bob it holds (the detector's path goes between them) is read by its direction
            rod = read_rod(stack, *scene[1:])
            if rod is not None:
                return rod[0], f"{rod[1]}, not {how}", None, False
    return xy, how, found, False


def objects(paths: np.ndarray) -> tuple[np.ndarray, ...]:
    """The paths (n, T, 2) that are in view in at least half the frames (a moving object, not
    something that crosses the view or a flicker), from left to right (the median x): the objects
    a state can name (`position@2`)."""
    kept = [p for p in paths if np.isfinite(p[:, 0]).mean() >= 0.5]
    return tuple(sorted(kept, key=lambda p: float(np.nanmedian(p[:, 0]))))


def measure(stack: np.ndarray) -> tuple[np.ndarray, float]:
    """(T, 2) change-weighted centroid (x, y) in the frames' pixels of the moving object in gray
    frames (T, H, W) uint8, NaN where nothing changes, and its mean area in pixels."""
    paths, area = measure_paths(stack, 1)
    return paths[0], area


def measure_paths(stack: np.ndarray, objects: int = 1, per_frame: bool = False) -> tuple[np.ndarray, Any]:
    """(objects, T, 2) the paths of the `objects` strongest moving things in gray frames
    (T, H, W) uint8 (see follow), the first the object's, NaN where a path has nothing, its places
    measured again where it passes a faint ghost (_unghosted); and the first object's mean area in
    pixels (per_frame: its area in each frame, (T,), NaN where unseen)."""
    sample, background, noise = static_scene(stack)
    found = {t: _candidates(stack[t], background, noise) for t in range(len(stack))}
    xy, area = _paths(found, len(stack), 1)
    xy = xy[0]
    seen = ~np.isnan(xy[sample, 0])
    if seen.any():
        size = math.sqrt(max(float(np.nanmean(area)), 1.0))
        h, w = background.shape
        ys, xs = np.mgrid[0:h, 0:w]
        total = np.zeros((h, w), np.float64)
        count = np.zeros((h, w), np.int32)
        for t in sample[seen]:
            far = (xs - xy[t, 0]) ** 2 + (ys - xy[t, 1]) ** 2 > (2 * size + 2) ** 2
            total += np.where(far, stack[t], 0)
            count += far
        clean = (total / np.maximum(count, 1)).round().astype(np.uint8)
        rebuilt = np.where(count >= max(3, len(sample) // 10), clean, background)
        # only the frames whose object lies near a pixel the rebuilt background changed (a ghost
        # where the object lingered) are measured again
        moved = np.abs(rebuilt.astype(np.int16) - background) > NOISE_SIGMAS * noise
        if moved.any():
            my, mx = np.nonzero(moved)
            reach = 4 * size + 4
            for t in range(len(stack)):
                if np.isnan(xy[t, 0]) or np.any((np.abs(mx - xy[t, 0]) < reach) & (np.abs(my - xy[t, 1]) < reach)):
                    found[t] = _candidates(stack[t], rebuilt, noise)
    paths, area = _paths(found, len(stack), objects)
    paths[0] = _unghosted(stack, sample, paths[0], area, background, noise)
    if per_frame:
        return paths, area
    return paths, float(np.nanmean(area)) if np.isfinite(area).any() else 0.0


def _median_far(stack: np.ndarray, frames: np.ndarray, xy: np.ndarray, radius: float,
                background: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's median over the frames in which the object lay farther than radius from it,
    (H, W) uint8 (background's where it never did), and how many such frames it had. A median,
    not a mean: a pendulum's string crosses most pixels near the pivot in some frames, and a mean
    keeps a smear of it that the median of all frames had not. The frames where the object lay
    near a pixel are set to 0 and 255 in turn there, which moves no median (to half a rank where
    their number is odd); rows are taken a band at a time, to hold a few MiB."""
    h, w = background.shape
    clean, count = background.copy(), np.full((h, w), len(frames), np.int32)
    r2 = radius * radius
    xs = np.arange(w, dtype=np.float64)
    band = max(1, (8 << 20) // max(1, len(frames) * w * 4))
    for y0 in range(0, h, band):
        ys = np.arange(y0, min(h, y0 + band), dtype=np.float64)
        near = np.stack([(ys[:, None] - xy[t, 1]) ** 2 + (xs[None, :] - xy[t, 0]) ** 2 <= r2 for t in frames])
        if not near.any():
            continue
        turn = (np.cumsum(near, axis=0, dtype=np.uint8) % 2).astype(bool)
        values = np.where(near, np.where(turn, np.uint8(0), np.uint8(255)), stack[frames, y0:y0 + len(ys)])
        clean[y0:y0 + len(ys)] = np.median(values, axis=0).round().astype(np.uint8)
        count[y0:y0 + len(ys)] -= near.sum(axis=0, dtype=np.int32)
    return clean, count


def _ghost(diff: np.ndarray, size: float) -> np.ndarray:
    """Where the static scene rebuilt without the object differs from the median one (diff, gray
    levels): averaged over a patch half the object's size across, by more than NOISE_SIGMAS spreads
    of that average over the frame. A ghost fainter than a pixel's own noise still weighs the
    change-weighted centroid: a block resting a quarter of the clip at its start left 1-5 gray
    levels where a pixel's 4 noise levels are 8, and its slide's first half read a 1.6% low."""
    k = max(3, int(round(size / 2)) | 1)
    mean = cv2.blur(diff.astype(np.float32), (k, k))
    spread = 1.4826 * float(np.median(np.abs(mean)))
    return np.abs(mean) > NOISE_SIGMAS * max(spread, GHOST_FLOOR)


def _unghosted(stack: np.ndarray, sample: np.ndarray, path: np.ndarray, area: np.ndarray,
               background: np.ndarray, noise: float) -> np.ndarray:
    """The object's path (T, 2) measured again, against the static scene rebuilt from the frames
    in which the object lay far from each pixel, in the frames where it passes a ghost fainter than
    a pixel's noise (_ghost); the place of the region nearest the path's, within half the object's
    size, is taken. Only the object's own places: which regions its path and the others go
    through was chosen above (against the median scene, rebuilt by a mean where a ghost passes 4
    noise levels) and stays so: rebuilt by this median for every region of every frame, the real
    drop's path switched between moving things and the object tracker took something else."""
    seen = np.isfinite(path[sample, 0])
    if not seen.any():
        return path
    size = math.sqrt(max(float(np.nanmean(area)), 1.0))
    clean, count = _median_far(stack, sample[seen], path, 2 * size + 2, background)
    rebuilt = np.where(count >= max(3, len(sample) // 10), clean, background)
    ghost = _ghost(rebuilt.astype(np.float32) - background, size)
    if not ghost.any():
        return path
    reach = int(math.ceil(size))  # a ghost farther than the object's size from its centroid is outside its region
    near = cv2.dilate(ghost.astype(np.uint8), np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)) > 0
    h, w = near.shape
    out = path.copy()
    for t in np.flatnonzero(np.isfinite(path[:, 0])):
        x, y = int(round(float(path[t, 0]))), int(round(float(path[t, 1])))
        if not (0 <= x < w and 0 <= y < h and near[y, x]):
            continue
        regions = _candidates(stack[t], rebuilt, noise)
        if not regions:
            continue
        dist = [math.hypot(c[0] - path[t, 0], c[1] - path[t, 1]) for c in regions]
        j = int(np.argmin(dist))
        if dist[j] <= 0.5 * size:
            out[t] = regions[j][:2]
    return out


def _paths(found: dict[int, list[tuple[float, float, float, float]]], length: int,
           objects: int) -> tuple[np.ndarray, np.ndarray]:
    """(objects, T, 2) each object's path through the frames' candidates (see follow), NaN where
    it has none, and the first object's area per frame."""
    xy = np.full((objects, length, 2), np.nan)
    area = np.full(length, np.nan)
    for o, path in enumerate(follow(found, length, objects)):
        for t, j in path.items():
            xy[o, t] = found[t][j][:2]
            if o == 0:
                area[t] = found[t][j][2]
    return xy, area


def follow(found: dict[int, list[tuple[float, float, float, float]]], length: int,
           objects: int = 1) -> list[dict[int, int]]:
    """The candidates (x, y, area, mass; each frame's strongest first) that make up each object's
    path: {frame: candidate index} per object, the strongest path first.

    A frame's strongest change is not always the object: something crossing the view (a person,
    a ball carried past) can outweigh it for a while. The path is the one through the frames'
    candidates that changes its step least and is strongest (a Viterbi pass over pairs of
    candidates): a change of step (an acceleration) costs by how much it exceeds the object's own
    motion from frame to frame (in units of that motion), squared, up to JUMP (the object is lost
    and found again elsewhere), so that a fast swing or a fall costs nothing; a candidate costs
    RANK for each place it stands below the frame's strongest, and earns up to MOVE where it
    moves (it lies far from every candidate of the frame before: a ghost, a wall's flicker or a
    hand that has let go stays put). A jump to something else and back costs far more than
    following a weaker object for a while. Each further object is the same pass over the
    candidates the earlier paths left."""
    frames = sorted(t for t in found if found[t])
    if not frames:
        return [{} for _ in range(objects)]
    first = np.array([found[t][0][:2] for t in frames])
    steps = np.hypot(*np.diff(first, axis=0).T) / np.maximum(np.diff(frames), 1) if len(frames) > 1 else np.zeros(0)
    size = math.sqrt(max(float(np.median([found[t][0][2] for t in frames])), 1.0))
    # the object's own motion per frame: the strongest candidates' typical step over the whole
    # clip (a local one would be a crossing thing's while it outweighs the object), and never
    # under a quarter of its size
    base = max(2.0 * float(np.median(steps)) if len(steps) else 1.0, 0.25 * size, 1.0)
    paths: list[dict[int, int]] = []
    taken: dict[int, set[int]] = {t: set() for t in frames}
    for _ in range(objects):
        path = _extended(found, frames, taken, base, _viterbi(found, frames, taken, base))
        paths.append(path)
        for t, j in path.items():
            taken[t].add(j)
    return paths


def _moving(found, t: int, xy: np.ndarray, base: float) -> np.ndarray:
    """(n,) how far each of frame t's candidates xy lies from every candidate of frame t - 1, in
    units of MOVE_SPAN object steps (at most 1; 0 where frame t - 1 has none)."""
    before = found.get(t - 1)
    if not before:
        return np.zeros(len(xy))
    near = np.linalg.norm(xy[:, None, :] - np.array([c[:2] for c in before])[None], axis=2).min(axis=1)
    return np.minimum(near / (MOVE_SPAN * base), 1.0)


def _extended(found, frames, taken, base: float, path: dict[int, int]) -> dict[int, int]:
    """The path with its main piece (the one that travels farthest between two jumps: a ball
    that falls, not the floor or the hand the path took before and after) kept and continued
    both ways through the candidates that move on from it most smoothly, whatever their rank:
    before a ball falls it is in the hand that lets it go, not a stronger change elsewhere."""
    ts = sorted(path)
    xy = np.array([found[t][path[t]][:2] for t in ts])
    if len(ts) < 3:
        return path
    step = np.diff(xy, axis=0) / np.diff(ts)[:, None]
    jumps, before = [], np.zeros(2)
    for i, v in enumerate(step):  # as the pass judged them: after a jump, against standing still
        lost = _excess(float(np.linalg.norm(v - before)), base) >= JUMP
        if lost:
            jumps.append(i + 1)  # the first frame after the jump
        before = np.zeros(2) if lost else v
    if not len(jumps):
        return path
    pieces = np.split(np.arange(len(ts)), jumps)
    main = max(pieces, key=lambda k: float(np.linalg.norm(np.ptp(xy[k], axis=0))))
    inside = {ts[k] for k in main}
    fixed = {t: (set(range(len(found[t]))) - {path[t]}) if t in inside else taken[t] for t in frames}
    return _viterbi(found, frames, fixed, base, rank=0.0, move=0.0)


def _viterbi(found, frames, taken, base: float, rank: float | None = None, move: float | None = None,
             jump: float | None = None) -> dict[int, int]:
    """The path through the candidates not yet taken: each state is a pair (the candidate before,
    this frame's), so that a step is compared with the one before it (rank, move, jump: the
    costs of follow, RANK, MOVE and JUMP unless given)."""
    rank = RANK if rank is None else rank
    move = MOVE if move is None else move
    jump = JUMP if jump is None else jump
    kept, options, xys, unary = [], [], [], []
    for t in frames:
        opts = [j for j in range(len(found[t])) if j not in taken[t]]
        if not opts:
            continue
        xy = np.array([found[t][j][:2] for j in opts])
        # the candidates' masses come from thresholds of their own (each the strongest of what the
        # earlier ones left), so only their order compares: each place down it costs RANK
        kept.append(t)
        options.append(opts)
        xys.append(xy)
        unary.append(rank * np.array(opts, dtype=np.float64) - move * _moving(found, t, xy, base))
    if not kept:
        return {}
    if len(kept) == 1:
        return {kept[0]: options[0][int(np.argmin(unary[0]))]}
    # a state is (the candidate before, this frame's, whether the step between them was a jump):
    # the step after a jump (the object taken up elsewhere) is compared with standing still, so
    # that a jump costs once; the first step is compared with standing still too
    velocity = (xys[1][None, :, :] - xys[0][:, None, :]) / (kept[1] - kept[0])  # (before, now, 2)
    excess = _excess(np.linalg.norm(velocity, axis=2), base)
    first = unary[0][:, None] + np.minimum(excess, jump) + unary[1][None, :]
    cost = np.stack([np.where(excess >= jump, np.inf, first), np.where(excess >= jump, first, np.inf)], axis=-1)
    back: list[np.ndarray] = []
    for k in range(2, len(kept)):
        step = (xys[k][None, :, :] - xys[k - 1][:, None, :]) / (kept[k] - kept[k - 1])  # (now, next, 2)
        kept_on = np.linalg.norm(step[None, :, :, :] - velocity[:, :, None, :], axis=3)  # (before, now, next)
        taken_up = np.broadcast_to(np.linalg.norm(step, axis=2)[None], kept_on.shape)
        excess = _excess(np.stack([kept_on, taken_up], axis=-1), base)  # (before, now, next, jumped before)
        total = cost[:, :, None, :] + np.minimum(excess, jump)
        _, n_now, n_next = kept_on.shape
        cost = np.empty((n_now, n_next, 2))
        arg = np.empty((n_now, n_next, 2), dtype=int)
        for lost in (0, 1):
            ways = np.where((excess >= jump) == bool(lost), total, np.inf).transpose(1, 2, 0, 3).reshape(n_now, n_next, -1)
            arg[..., lost] = np.argmin(ways, axis=2)
            cost[..., lost] = np.min(ways, axis=2)
        cost += unary[k][None, :, None]
        back.append(arg)
        velocity = step
    now, nxt, lost = np.unravel_index(int(np.argmin(cost)), cost.shape)
    chosen = [0] * len(kept)
    chosen[-2], chosen[-1] = int(now), int(nxt)
    for k in range(len(kept) - 1, 1, -1):
        before, lost = divmod(int(back[k - 2][chosen[k - 1], chosen[k], lost]), 2)
        chosen[k - 2] = before
    return {t: options[k][chosen[k]] for k, t in enumerate(kept)}


def _excess(change: np.ndarray, base: float) -> np.ndarray:
    """What a change of step costs before JUMP caps it: nothing within the object's own motion
    (base), beyond it the excess squared."""
    return np.maximum(change / base - 1.0, 0.0) ** 2


CANDIDATES = 4  # the strongest changes each frame keeps for the path to choose from
WEAKEST = 0.02   # a candidate's least mass, as a share of the frame's strongest
RANK = 1.0       # what following the frame's k-th strongest candidate costs a frame, per place down
JUMP = 40.0      # what losing the object and taking it up elsewhere costs: the rank of forty frames
MOVE = 2.0       # what a frame's candidate that moves earns (see follow)
MOVE_SPAN = 4.0  # ... in full where it lies this many object steps from the frame before's candidates


def _candidates(frame: np.ndarray, background: np.ndarray, noise: float) -> list[tuple[float, float, float, float]]:
    """Up to CANDIDATES separate changes in a frame, strongest first, each (x, y, area, mass):
    the strongest as _measure_one finds it, then the strongest of what is left once its region
    is set aside, and so on."""
    change = cv2.absdiff(frame, background)
    out: list[tuple[float, float, float, float]] = []
    levels: dict[int, float] = {}  # the frame's noise level per shrink, measured once (its medians cost)
    for _ in range(CANDIDATES):
        found = _measure_one(change, noise, levels)
        if found is None or (out and found[3] < WEAKEST * out[0][3]):
            break
        out.append(found[:4])
        x0, y0, x1, y1 = found[4]
        change[y0:y1, x0:x1] = 0
    return out


def _locate_level(small: np.ndarray, noise: float, k: int) -> float:
    """The level a k x k block's average change (small) must pass to stand out from the noise: at
    least NOISE_SIGMAS / k of a pixel's noise, and NOISE_SIGMAS spreads of the blocks' own values
    above their median. An average of absolute changes stays above zero, and a video codec's noise
    is correlated over its blocks, so the blocks' spread is measured, not taken as 1/k of the
    pixels' (a 240 fps throw at 320x240: the median block 3, the spread 1.5 for a noise of 3.5,
    where 4 / k put the level at 3.5: the blocks of noise over it joined into wide regions that
    outweighed a ball 3 pixels across)."""
    level = NOISE_SIGMAS * noise / k
    if k == 1:
        return level
    sample = small[::2, ::2].astype(np.float32)
    middle = float(np.median(sample))
    spread = 1.4826 * float(np.median(np.abs(sample - middle)))
    return max(level, middle + NOISE_SIGMAS * max(spread, 0.5))


def _measure_one(change: np.ndarray, noise: float,
                 levels: dict[int, float]) -> tuple[float, float, float, float, tuple[int, int, int, int]] | None:
    """The strongest change's centroid (x, y), area, mass (its change over the noise, summed) and box,
    its region located on the change shrunk by LOCATE where the frame allows; where nothing stands
    out there, looked for again at half that shrink (a ball two pixels across that straddles four
    blocks leaves a quarter of its change in each). levels: the frame's level per shrink
    (_locate_level), filled on first need: what later candidates of the same frame compare against."""
    k = LOCATE if min(change.shape) >= 16 * LOCATE else 1
    found = _measure_at(change, noise, k, levels)
    return found if found is not None or k == 1 else _measure_at(change, noise, k // 2, levels)


def _measure_at(change: np.ndarray, noise: float, k: int,
                levels: dict[int, float]) -> tuple[float, float, float, float, tuple[int, int, int, int]] | None:
    """_measure_one with the region located on the change shrunk by k."""
    h, w = change.shape
    small = cv2.resize(change[:h - h % k, :w - w % k], (w // k, h // k), interpolation=cv2.INTER_AREA) if k > 1 else change
    peak = float(small.max())
    if k not in levels:
        levels[k] = _locate_level(small, noise, k)
    low = levels[k]
    if peak <= low:
        return None
    hot = cv2.threshold(small, max(low, CORE * peak), 1, cv2.THRESH_BINARY)[1]
    n, labels, stats, _ = cv2.connectedComponentsWithStats(cv2.dilate(hot, None), connectivity=8)
    if n < 2:
        return None
    if n == 2:
        best = 1
    else:
        mass = np.bincount(labels.ravel(), weights=(small * hot).ravel(), minlength=n)
        best = int(np.argmax(mass[1:])) + 1
    bx, by, bw, bh = (int(v) for v in stats[best, :4])
    # the region at full resolution, one shrunk pixel wider on each side (its edge pixels were averaged)
    x0, y0, x1, y1 = max(0, (bx - 1) * k), max(0, (by - 1) * k), min(w, (bx + bw + 1) * k), min(h, (by + bh + 1) * k)
    box = change[y0:y1, x0:x1].astype(np.float32)
    if n > 2:  # only the chosen region: another may reach into its box
        inside = labels[y0 // k:(y1 + k - 1) // k, x0 // k:(x1 + k - 1) // k] == best
        grown = np.repeat(np.repeat(inside, k, axis=0), k, axis=1)[:box.shape[0], :box.shape[1]]
        mask = np.zeros(box.shape, dtype=box.dtype)  # the last h % k rows (w % k columns) lie off the shrunk grid
        mask[:grown.shape[0], :grown.shape[1]] = grown
        box *= mask
    # the core's pixels and the ring of partly covered pixels around it, each weighted by its change
    # over the noise: a core cut at a share of the peak drops the partly covered edge pixels unevenly,
    # which moves a small object's centroid by a good part of a pixel
    core = (box > max(NOISE_SIGMAS * noise, CORE * float(box.max()))).astype(np.uint8)
    opened = cv2.morphologyEx(core, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    if opened.any():
        core = opened
    weight = np.where(cv2.dilate(core, None) > 0, np.maximum(box - NOISE_SIGMAS * noise, 0.0), 0.0)
    total = float(weight.sum())
    if total <= 0:
        return None
    return (x0 + float(weight.sum(axis=0) @ np.arange(x1 - x0)) / total,
            y0 + float(weight.sum(axis=1) @ np.arange(y1 - y0)) / total, float(np.count_nonzero(weight)),
            total, (x0, y0, x1, y1))
