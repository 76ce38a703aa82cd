"""The stretch of a measured path that one trajectory of the equation explains.

A one-way clip is rarely one trajectory from its first frame to its last: a ball is held, then
dropped, then bounces; a block rests, slides, rests. A fit over all of it averages laws that do not
hold together (a block at rest obeys x'' = a with a = 0). The stretch is found, not typed:

1. where it moves: frames at rest are those where the path stays within REST_SIGMAS noise over
   REST_SECONDS (or REST_FRAMES frames, where fewer); the candidates are the runs between rests (a path that never rests is taken
   whole: the search is for a motion between rests, and on generated falls and two-state paths
   it only trimmed frames that held the constants);
2. the noise: the robust spread of the third differences of the moving frames (motion that is
   smooth over a few frames leaves them; white noise of spread s gives them a spread of sqrt(20) s);
3. the level one trajectory reaches locally: the median misfit of short windows (seeds) spread
   over each candidate, or the noise where that is larger; a candidate whose one trajectory
   stays within TOL of it is taken whole (and grown into the rests);
4. otherwise grown from the seeds: each is grown at both ends (into the rests too: a motion starts from rest), a step at a time
   (halved on a miss), for as long as one trajectory still fits with a misfit within TOL of the noise on the new frames and on the whole;
   one more seed sits in the middle of the run's longest one-way run (a fall between a hand and
   the floor) and grows to a misfit of MAIN_SLACK of the travel (a camera's perspective bends a
   long fall by more than its noise); the stretch that travels farthest wins (a rest is one
   trajectory too, and may last longer than the motion).

Why it ends is said in words: the clip ends, the thing stops (a rest follows), or the path leaves
the trajectory (by how many times the noise).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

REST_SECONDS = 0.2
# ... or REST_FRAMES frames, where fewer: a fast camera sees a short hold in many frames (a 240 fps
# throw held 0.1 s, 24 frames, was no rest, and one trajectory through the hold and the flight gave
# g -3873 px/s^2 for 1255); at 60 fps and below the window is REST_SECONDS' as before
REST_FRAMES = 20
REST_SIGMAS = 6.0
TOL = 2.5  # new frames may miss the trajectory by this many noise spreads (RMS), the whole by TOL / 2
SEEDS = 4
BREAK = 10.0  # a moving run is cut inside only where one trajectory misses it by this many local levels
MIN_SEED = 12
RUN_SLACK = 0.02  # a one-way run may turn back by this share of the path's travel (one_way_runs)
RUN_JUMP = 0.2    # ... and breaks at a step longer than this share of it
MAIN_RUN = 0.5    # a one-way run over this share of the travel is the motion: one seed is its middle
MAIN_SLACK = 0.0075  # ... grown while one trajectory misses the new frames by at most this share of the travel
SETTLED = 0.01    # an end of the clip at least two rest windows long that stays within this share of the
SETTLED_SPEED = 0.05  # travel is a rest too, where it moves at most this share of the speed just before it
HELD_SHARE = 0.25  # a path that never rests is cut by the search only where what it leaves out before the
                   # stretch travels less than this share of the stretch (a hand that holds it, nearly still)


@dataclass
class Stretch:
    """Frames [start, end) of the path (exclusive end) and why each end is where it is."""

    start: int
    end: int
    why_start: str
    why_end: str
    noise: float

    def to_dict(self, dt: float, offset: int = 0, source: str = "found") -> dict:
        return {"start_frame": self.start + offset, "end_frame": self.end + offset,
                "start_s": (self.start + offset) * dt, "end_s": (self.end + offset) * dt,
                "reason": f"{self.why_start}; {self.why_end}", "source": source}


def noise_level(x: np.ndarray) -> float:
    """Robust spread of a path's frame-to-frame noise (per column, the largest), from third differences."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    if len(x) < 8:
        return float(np.std(x)) or 1e-12
    d3 = np.diff(x, n=3, axis=0)
    mad = np.median(np.abs(d3 - np.median(d3, axis=0)), axis=0)
    return max(float((1.4826 * mad / math.sqrt(20.0)).max()), 1e-12 * max(float(np.ptp(x)), 1.0))


def rest_window(dt: float) -> int:
    """The frames a rest must last: REST_SECONDS, at most REST_FRAMES, at least 3."""
    return max(3, min(int(round(REST_SECONDS / dt)), REST_FRAMES))


def at_rest(x: np.ndarray, dt: float, noise: float) -> np.ndarray:
    """(T,) True where the path stays within REST_SIGMAS noise spreads for rest_window frames
    around it, at the clip's start or end."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    w = rest_window(dt)
    T = len(x)
    rest = np.zeros(T, dtype=bool)
    if T < w:
        return rest
    # the span without the window's most extreme frame each way: a tracker's one-frame glitch
    # (a centroid off by a pixel) is not motion
    ordered = np.sort(np.lib.stride_tricks.sliding_window_view(x, w, axis=0), axis=-1)
    cut = 1 if w >= 6 else 0
    span = (ordered[..., w - 1 - cut] - ordered[..., cut]).max(axis=1)
    still = span <= REST_SIGMAS * noise
    for i in np.flatnonzero(still):
        rest[i:i + w] = True
    head, tail = settled_ends(x, w)
    rest[:head] = True
    rest[T - tail:] = True
    # only a stillness that opens or closes the clip is a rest (before a release, after a stop): a
    # swing's turning points are still for a few frames too (the real ornament was cut to its last
    # 2 s, L +1.9%), and a motion that pauses and goes on is still one clip's motion
    inner = np.flatnonzero(~rest)
    if len(inner):
        rest[inner[0]:inner[-1] + 1] = False
    return rest


def settled_ends(x: np.ndarray, w: int) -> tuple[int, int]:
    """How many frames at the clip's start and at its end (x: (T, k)) have settled: an end at least
    2w frames long whose span (per column; a frame's median with its neighbours, so that a
    one-frame glitch does not count) stays within SETTLED of the path's travel, and whose speed
    over it is at most SETTLED_SPEED of the speed over the w frames next to it: a ball come to rest
    where it lands, which a tracker at 240 fps reads to 0.006 px from frame to frame and which
    wanders by 0.02 px in a codec's slow noise (7 of those spreads over 20 frames: no rest by
    REST_SIGMAS, and the flight was grown into 35 frames of it: g 0.13 for 19.2). A motion that
    slows smoothly (a drain, a decay, a swing dying out) is as slow just before as in its end."""
    T = len(x)
    travel = float(np.ptp(x, axis=0).max()) if T else 0.0
    if T < 3 * w or travel <= 0:
        return 0, 0
    smooth = np.median(np.stack([x[:-2], x[1:-1], x[2:]]), axis=0)
    smooth = np.concatenate([x[:1], smooth, x[-1:]])

    def settled(y: np.ndarray) -> int:
        # y runs from the end of the clip inward: the longest settled end, 0 if none
        low, high = np.minimum.accumulate(y), np.maximum.accumulate(y)
        ok = ((high - low) <= SETTLED * travel).all(axis=1)  # true up to a frame, false after it
        n = len(ok) if ok.all() else int(np.argmin(ok))
        if n < 2 * w or n + w > len(y):
            return 0
        own = float(np.abs(high[n - 1] - low[n - 1]).max()) / n
        before = float(np.abs(y[n - 1 + w] - y[n - 1]).max()) / w
        return n if own <= SETTLED_SPEED * before else 0

    return settled(smooth), settled(smooth[::-1])


def find_stretch(x: np.ndarray, dt: float, fit: Callable[[int, int], np.ndarray | None], *,
                 min_len: int = MIN_SEED, search: bool = False) -> Stretch:
    """The longest stretch [start, end) of the path x (T, k) that one trajectory explains.
    fit(a, b): the residual (b - a, k) of one trajectory fitted to frames [a, b), in x's units,
    or None where it cannot be fitted (fit may warm-start from its previous call). search: look
    inside a path that never rests too (a hand that holds a pendulum is never quite still): the
    whole is kept where one trajectory misses it by less than a break (train/pieces.py)."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    T = len(x)
    rest = at_rest(x, dt, noise_level(x))
    # the noise of a moving thing is not that of a still one (a blob on the pixel grid, motion blur):
    # the tolerance comes from the moving frames, where there are enough of them
    noise = noise_level(x[~rest]) if int((~rest).sum()) >= 8 else noise_level(x)
    if not rest.any() and not search:
        # it never rests: the clip is the motion. Searching it cut a clean path of two oscillators
        # (8 s) to its last 1.25 s (a 4.27 for 4.0): the search's short fits, their learned scale
        # held at the windows', miss a long path they would fit from a better start
        return Stretch(0, T, _why_start(0, rest, dt), _why_end(T, T, rest, dt), noise)
    runs = _runs(~rest)
    best: tuple[int, int] | None = None
    best_at = 0.0  # the level the best stretch was grown at
    # a closing rest is entered at the noise's level, whatever slack the motion had: past a stop
    # that friction makes (a puck, a block), x'' = -a turns back by a t^2 / 2, which a slack for a
    # long path's bends (MAIN_SLACK) let the growth take 0.19 s of (a generated puck: a -3.4%)
    moving = np.flatnonzero(~rest)
    closing = int(moving[-1]) + 1 if len(moving) else T

    def reach(span: tuple[int, int] | None) -> float:
        # how far the path moves over a stretch: a rest (a ball on the floor, a hand that holds it)
        # is one trajectory too, with the constants of standing still, and may last longer than
        # the motion the clip is about
        return -1.0 if span is None else float(np.ptp(x[span[0]:span[1]], axis=0).max()) if span[1] > span[0] else 0.0

    for a, b in sorted(runs, key=lambda r: r[0] - r[1]):
        if b - a < min_len or (best is not None and reach((a, b)) <= reach(best)):
            continue
        seed = max(min_len, (b - a) // (2 * SEEDS))
        starts = np.linspace(a, b - seed, min(SEEDS, max(1, (b - a) // seed))).astype(int)
        seeds = {int(s): _rms(fit(int(s), int(s) + seed)) for s in starts}
        # what one trajectory achieves locally: a tracker's small systematic errors (the centroid of
        # a blob, a swing read as a position) stand above the frame-to-frame noise everywhere alike
        # the better half of the seeds: a hand in front of a drain, its emptied end, miss one trajectory
        # where they are, and two such seeds of four set the median (the real bottle: 0.006 for 0.0009)
        local = sorted(v for v in seeds.values() if v is not None)
        level = max(noise, float(np.median(local[:max(1, (len(local) + 1) // 2)]))) if local else noise
        whole = _rms(fit(a, b))
        # the run is one trajectory, or misses it by less than a break does (a bounce, a hand: many
        # times the local level): grow it into the rests. A long real swing misses one trajectory of
        # an idealised equation by a few local levels (air drag is not linear): cutting it there
        # kept the real ornament's last 2 s (L +1.9%)
        if whole is not None and whole <= BREAK * level:
            best, best_at = _grow(fit, a, b, 0, T, level, whole, stop=(closing, noise)) or (a, b), level
            continue
        grown_from = [(int(s), level, seeds[int(s)]) for s in starts]
        main = _main_seed(x[a:b], seed)
        if main is not None:
            # the middle of the motion the run is about (a fall between the hand and the floor,
            # which the evenly spread seeds may straddle), grown up to where one trajectory misses
            # the new frames by MAIN_SLACK of the run's travel (or BREAK times the seed's level, if
            # more). A camera that looks up a wall bends the real drop's whole fall by 13 times the
            # ball's noise, 0.2% of its travel; the hand before and the floor after miss it by a
            # few percent and by all of it
            s = a + main
            own = _rms(fit(s, s + seed))
            if own is not None:
                limit = max(BREAK * max(level, own), MAIN_SLACK * reach((a, b)))
                grown_from.append((s, limit / TOL, own))
        for s, at, first in grown_from:
            # a seed inside the best stretch grows into it again, unless it may miss by more (the
            # main seed: a generated puck's first seed grew to 16 frames around it, and it was
            # skipped, the slide's 80 frames left out)
            if best is not None and best[0] <= s and s + seed <= best[1] and at <= best_at:
                continue
            grown = _grow(fit, s, s + seed, 0, T, at, first, stop=(closing, noise))
            if grown is not None and reach(grown) > reach(best):
                best, best_at = grown, at
    if best is None:
        best = (0, T)
    if best[1] > closing:
        best = (best[0], _turned(x, fit, best[0], best[1], closing, min_len, noise))
    if not rest.any() and reach((0, best[0])) >= HELD_SHARE * reach(best):
        # a path that never rests is searched for a hand that holds it before the motion (search):
        # what the search leaves out before the stretch must go nearly nowhere. Where it moves as
        # the stretch does, the search's short fits have missed a long path they would fit from a
        # better start (the two oscillators' 8 s cut to their last 2 s: a 4.42 for 4.0): the clip
        # is the motion. (Its end may be cut: a long real swing leaves an idealised equation.)
        best = (0, T)
    return Stretch(best[0], best[1], _why_start(best[0], rest, dt), _why_end(best[1], T, rest, dt), noise)


def _main_seed(x: np.ndarray, seed: int) -> int | None:
    """Where a seed of `seed` frames starts that is centred on the middle of a path's (T, k)
    longest one-way run (its column of largest range), where that run covers more than
    MAIN_RUN of the travel and is longer than the seed; None otherwise."""
    column = x[:, int(np.argmax(np.ptp(x, axis=0)))]
    way, (start, end, share) = max(one_way_runs(column).items(), key=lambda item: item[1][2])
    if share <= MAIN_RUN or end - start <= seed:
        return None
    run = way * column[start:end]
    middle = start + int(np.argmax(run >= run.min() + 0.5 * np.ptp(run)))
    return int(min(max(middle - seed // 2, start), end - seed))


def one_way_runs(x: np.ndarray) -> dict[int, tuple[int, int, float]]:
    """The longest one-way run of a path (T,) each way (+1: rising, -1: falling): {way: (start,
    end, share)}, frames [start, end) and the share of the path's travel (its range) it covers.
    A run goes on while the path does not turn back by more than RUN_SLACK of the travel (noise, a
    blurred frame) and breaks at a step longer than RUN_JUMP of it (a track taken up by something
    else): a ball held, dropped and bouncing covers almost all of its travel in one run, the
    bounce a fifth of it the other way; a swing covers all of it both ways."""
    x = np.asarray(x, dtype=np.float64)
    travel = float(np.nanmax(x) - np.nanmin(x)) if np.isfinite(x).any() else 0.0
    best = {1: (0, 0, 0.0), -1: (0, 0, 0.0)}
    if len(x) < 3 or not travel > 0:
        return best
    for way in (1, -1):
        y = way * np.nan_to_num(x, nan=float(np.nanmedian(x))) / travel
        start, low, high = 0, y[0], y[0]
        for i in range(1, len(y)):
            if abs(y[i] - y[i - 1]) > RUN_JUMP or y[i] < high - RUN_SLACK:
                start, low, high = i, y[i], y[i]  # a new run starts here
            else:
                high = max(high, y[i])
            if high - low > best[way][2]:
                best[way] = (start, i + 1, float(high - low))
    return best


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def _turned(x: np.ndarray, fit, a: int, b: int, closing: int, min_len: int, noise: float) -> int:
    """The end of the stretch [a, b) that runs into the clip's closing rest (from frame `closing`):
    where its trajectory turns back there by more than a rest may move (REST_SIGMAS noise spreads),
    the frame after the turn. A thing that friction stops (a puck, a block) comes to rest where its
    speed reaches zero, and x'' = -a would turn back from there: the rest's first frames, near the
    turn, still fit. A decay that settles (a drain, a light) does not turn back, and a swing that
    dies out in the noise turns back by less."""
    r = fit(a, b)
    if r is None or r.shape != x[a:b].shape:
        return b
    model = x[a:b] + r  # the trajectory (the residuals are the prediction less the path)
    c = int(np.argmax(np.ptp(model, axis=0)))
    first = max(closing - a - 1, 1)
    way = np.sign(model[first, c] - model[0, c])
    back = np.flatnonzero(way * np.diff(model[first - 1:, c]) < 0)
    if not len(back):
        return b
    turn = first + int(back[0]) - 1  # the frame the trajectory turns at
    moved = float(np.max(way * (model[turn, c] - model[turn:, c])))
    end = a + turn + 1
    return end if moved > REST_SIGMAS * noise and end - a >= min_len else b


def _grow(fit, a: int, b: int, lo: int, hi: int, noise: float, first: float | None,
          stop: tuple[int, float] | None = None) -> tuple[int, int] | None:
    """[a, b) (its fit's RMS `first`) grown within [lo, hi) while one trajectory still fits it: at
    each end, a bisection for the longest extension whose added frames still fit (a dozen fits,
    not one per frame). stop (frame, level): the frames from `frame` on (a closing rest) are
    added only where they miss by at most TOL times max(level, first)."""
    if first is None or first > TOL / 2 * noise:
        return None
    level = max(first, noise)
    for side in ("end", "start"):
        good, bad = 0, (hi - b if side == "end" else a - lo) + 1
        ext = min(bad - 1, max(1, (b - a) // 2))  # first a step of half the stretch: most ends are near
        while bad - good > 1:
            na, nb = (a, b + ext) if side == "end" else (a - ext, b)
            r = fit(na, nb)
            new = None if r is None else r[:ext] if side == "start" else r[r.shape[0] - ext:]
            resting = None
            if r is not None and side == "end" and stop is not None and nb > stop[0]:
                resting = r[r.shape[0] - (nb - max(stop[0], b)):]
            if (r is not None and _rms(r) <= TOL / 2 * level and _rms(new) <= TOL * level
                    and (resting is None or _rms(resting) <= TOL * max(stop[1], first))):
                good = ext
            else:
                bad = ext
            ext = (good + bad) // 2
        a, b = (a, b + good) if side == "end" else (a - good, b)
    return a, b


def _rms(r: np.ndarray | None) -> float | None:
    return None if r is None or r.size == 0 else float(np.sqrt(np.mean(np.square(r))))


def _why_start(start: int, rest: np.ndarray, dt: float) -> str:
    if start == 0:
        return "from the clip's first frame"
    if start > 0 and rest[start - 1]:
        return f"the motion starts at {start * dt:.3g} s (at rest before)"
    return f"before {start * dt:.3g} s the path does not follow one trajectory of the equation"


def _why_end(end: int, T: int, rest: np.ndarray, dt: float) -> str:
    if end >= T:
        return "to the clip's last frame"
    if rest[min(end, T - 1)] or rest[min(end + 1, T - 1)]:
        return f"the motion stops at {end * dt:.3g} s"
    return f"from {end * dt:.3g} s the path leaves one trajectory of the equation"
