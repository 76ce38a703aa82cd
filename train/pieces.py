"""The pieces of a measured path: every stretch where one trajectory of the equation holds, and
the events between them.

A clip is filmed with what happens around the motion: a hand holds the pendulum at its angle and
lets go, a cart bounces off its bumper and climbs again, a ball bounces, a block rests, slides and
stops. Each stretch between two such events is one trajectory of the equation with a starting
state of its own; the constants are the same in all of them (train/joint.py fits them together).

1. Impacts: a bounce changes the velocity between two frames: the velocity read from a few frames
   before a frame and from a few after it differ far beyond their noise, and by a good share of
   the speed (impacts), and one trajectory across it misses far more than one each side (_felt);
   the frames at the impact are on neither trajectory and are left out.
2. Each stretch between impacts is searched as the single stretch is (train/stretch.py,
   find_stretch with search on): a rest before or after it (held still, stopped), or a part that
   one trajectory cannot explain (a hand that moves it, a tracker that lost it), is cut off.
3. Two neighbours that one trajectory explains together (an impact that was noise) are joined; a
   first or last piece that goes nowhere (a hand that holds it still enough) is a hold or a stop.
4. A release is a start: after a hold the first piece starts where the path leaves its place as a
   parabola from rest (release), whatever the search grew into the hold.

Every event is said in words (Pieces.describe): "held until 1.52 s; released; 6 flights between
bounces at 1.23, 2.01, ... s; to the clip's last frame".
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .stretch import BREAK, MIN_SEED, REST_SIGMAS, TOL, at_rest, find_stretch, noise_level, rest_window, settled_ends

JUMP = 6.0        # an impact: the velocities either side of a frame differ by this many times their noise
MOVING = 2.0      # ... and turn round, at least this many times that noise fast either side
RELEASE_S = 0.15  # seconds either side of a release its parabola from rest is fitted over
RELEASE_SPAN = 4  # ... searched this many of those either side of where the piece was found to start
RELEASE_MIN = 3   # ... with at least this many frames of the hold before it
THROWN = 4.0      # ... and thrown (a speed of its own) where that leaves this many times less unexplained
HOLD_SHARE = 0.03  # a first or last piece that travels less than this share of the longest is a hold or a stop
SIDE_S = 0.12     # seconds each side a velocity is read from, SIDE_FRAMES frames at least and at most
SIDE_FRAMES = (3, 12)
SCALES = (1, 2, 3)  # ... and from this many times as many (see impacts), where a parabola each side
PARABOLIC = 2.0    # ... misses its frames by at most this many times the noise
GAP = 1           # ... leaving out this many at the frame: the impact falls between two frames
PLACE = 6.0       # ... and the place either side's parabola gives at the frame differs by at most this
#                   many times its noise beyond what the jump moves it in GAP frames (no jump of place)
KINK = 4.0        # ... and no smooth motion runs through the frames around it: a quartic across both
#                   sides misses them by this many times the noise (a swing's turning point, read
#                   from coarse frames, has sides whose parabolas disagree, but a quartic follows it),
KINK_SHARP = (1.2, 1.5)  # or by this many times the noise and this many times what a parabola each
#                   side misses them by (a fast bounce read from few frames: a quartic rounds its
#                   corner to within KINK noise, the two parabolas follow it; a swing's turn is the
#                   other way round, its sides' parabolas miss it 4 times more than the quartic)
SPLIT_GAIN = 4.0  # a piece one trajectory misses by BREAK times the noise is split at its strongest turn of
#                   the velocity (impacts' threshold halved, no smooth-motion guard: a slow last bounce)
#                   where one trajectory each side misses it by this many times less
SPLITS = 3        # ... at most this many times over
SHORT = 6      # a stretch between two impacts this many frames long, one trajectory explaining it whole, is a
#                piece though shorter than a seed (a ball's third flight filmed at 30 fps is 7 frames)
LOST_GAP = 1.0  # pieces apart by more than this many velocity windows that no impact explains are two
#                 motions (a ball that rolls away and is picked up): the one that travels farther is kept
FORCED = TOL  # a first (last) piece whose trajectory misses by more than this many times what it misses
#               without its first (last) release window starts with a push (ends with an impact) (_unforced)
JOIN = 2.0     # two neighbours are one trajectory where it misses their union by at most this many times
#                their own misfits (or the noise)


# how each way a motion ends is said, in the summary line and on track.png
ENDS = {"stop": "comes to rest", "lost": "leaves the trajectory", "gone": "leaves the view"}


@dataclass
class Event:
    """What happens at a frame: hold, push (a hand that moves it until then, as a puck is pushed),
    release, bounce, stop, moved (by something else), lost (the
    path leaves the trajectory), gone (the object leaves the view: the reader's track loses it),
    enter (the object comes into the view: the first piece starts where it is whole in it)."""

    frame: int
    kind: str

    def to_dict(self, dt: float) -> dict:
        return {"frame": self.frame, "time_s": self.frame * dt, "kind": self.kind}


@dataclass
class Pieces:
    """The stretches [start, end) of a path that one trajectory each explains, in time order, and
    the events between and around them."""

    spans: list[tuple[int, int]]
    events: list[Event] = field(default_factory=list)
    noise: float = 0.0
    # stretches one trajectory explains whose constants are another motion's (train/joint.py,
    # other_motions: a ball rolling on the floor, a hand), left out of the fit: [start, end) frames
    left_out: list[tuple[int, int]] = field(default_factory=list)

    def without(self, drop: list[int]) -> "Pieces":
        """These pieces less those at the indices drop, which are said as left out; where they
        follow the last kept piece, the motion is lost there, and their events go with them."""
        kept = [s for i, s in enumerate(self.spans) if i not in drop]
        gone = [s for i, s in enumerate(self.spans) if i in drop]
        end, events = kept[-1][1], list(self.events)
        if gone[-1][1] > end:  # the last pieces are another motion: the equation's ends with the last kept
            events = [e for e in events if e.frame < end] + [Event(end, "lost")]
        return Pieces(kept, events, self.noise, self.left_out + gone)

    def describe(self, dt: float, t0: float = 0.0, n_frames: int | None = None) -> str:
        """The pieces and their events in one line, times from t0 seconds at frame 0."""
        t = lambda f: f"{t0 + f * dt:.2f} s"  # noqa: E731 - a local format
        words: list[str] = []
        kinds = [e.kind for e in self.events]
        hold = next((e for e in self.events if e.kind in ("hold", "moved")), None)
        if any(e.kind == "enter" for e in self.events):
            words.append("enters the view")
        if hold is not None:
            words.append(("held still until " if hold.kind == "hold" else
                          "moved by something other than the equation (a hand?) until ") + t(hold.frame))
            push = next((e for e in self.events if e.kind == "push"), None)
            if push is not None:
                words.append(f"pushed until {t(push.frame)}")
            elif "release" in kinds:
                words.append("released")
        bounces = [e.frame for e in self.events if e.kind == "bounce"]
        n = len(self.spans)
        if bounces:
            shown = ", ".join(t(b)[:-2] for b in bounces[:8]) + (", ..." if len(bounces) > 8 else "")
            words.append(f"{n} flights between {len(bounces)} bounce{'s' if len(bounces) > 1 else ''} at {shown} s")
        elif n > 1:
            words.append(f"{n} pieces, apart at " + ", ".join(t(a) for a, _ in self.spans[1:]))
        else:
            words.append(f"one trajectory from {t(self.spans[0][0])} to {t(self.spans[0][1])}" if self.spans
                         else "no stretch that one trajectory explains")
        if self.left_out:
            words.append("left out as another motion: " + ", ".join(f"{t(a)[:-2]}-{t(b)}" for a, b in self.left_out))
        end = next((e for e in self.events if e.kind in ENDS), None)
        if end is not None:
            words.append(f"{ENDS[end.kind]} at {t(end.frame)}")
        elif self.spans and n_frames is not None and self.spans[-1][1] >= n_frames:
            words.append("to the clip's last frame")
        return "; ".join(words)

    def to_dict(self, dt: float, n_frames: int | None = None) -> dict:
        """Plain data (meta["pieces"]): frames of the fitted frames, end exclusive, and seconds."""
        return {"pieces": [[a, b] for a, b in self.spans], "pieces_s": [[a * dt, b * dt] for a, b in self.spans],
                "events": [e.to_dict(dt) for e in self.events], "n_frames": n_frames,
                "summary": self.describe(dt, 0.0, n_frames), "noise": self.noise,
                "left_out": [[a, b] for a, b in self.left_out]}

    @classmethod
    def from_dict(cls, d) -> "Pieces":
        return cls([(int(a), int(b)) for a, b in d.get("pieces", ())],
                   [Event(int(e["frame"]), str(e["kind"])) for e in d.get("events", ())], float(d.get("noise", 0.0)),
                   [(int(a), int(b)) for a, b in d.get("left_out", ())])


def impacts(x: np.ndarray, noise: float, lo: int, hi: int, dt: float) -> list[tuple[int, int]]:
    """Frames [a, b) around each velocity jump of the path x (T, k) within [lo, hi), in order.

    Before and after every frame a parabola is fitted to SIDE_S seconds of frames (leaving GAP frames at the
    frame itself: the impact falls between two frames); each gives the velocity at the frame. A
    jump is where they differ by JUMP times their noise (exact for a parabola's fit) and point
    opposite ways, each MOVING times that noise fast (a bounce turns the motion round; a release
    starts from rest and a swing's turning point is as slow either side); the local largest of such
    frames, with the GAP frames either side, is the impact. The velocities are read again from
    SCALES times as many frames (at most SIDE_FRAMES' largest): a slow bounce (a cart's fourth,
    0.7 m/s at 30 fps) is lost in the noise of a few frames' velocity and plain in that of many,
    and a jump at any of those lengths counts."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    SIDE = _side(dt)
    sides = sorted({min(k * SIDE, SIDE_FRAMES[1]) for k in SCALES})
    score = np.max([_jumps(x, noise, lo, hi, side, JUMP, guard=True, parabolic=True) for side in sides],
                   axis=0)
    out: list[tuple[int, int]] = []
    for i in np.flatnonzero(score > 0):
        if score[i] < score[max(i - SIDE, 0):i + SIDE + 1].max():
            continue  # not the local largest
        if out and i - GAP < out[-1][1]:
            continue
        out.append((int(i - GAP), int(i + GAP + 1)))
    return out


def _felt(cuts: list[tuple[int, int]], fit, noise: float, lo: int, hi: int) -> list[tuple[int, int]]:
    """The impacts the equation feels: one trajectory across an impact's two neighbouring stretches
    (up to the impacts either side) misses them by SPLIT_GAIN times what the better of the two
    misses alone by (or the noise), as a split in _parts must. impacts judges a turn in units of the
    frames' scatter, and a reading whose error is slow shows more than its scatter at a smooth turn
    (a generated spring's can read 0.19 px RMS off, 0.6 px near one trough, against 0.043 px of
    scatter: two troughs in 9.6 s were taken for bounces, and the last 0.9 s, a piece of its own,
    gave w2 5% low); across a bounce one trajectory cannot turn the motion round and misses by far
    more. A stretch too short to fit keeps its impact."""
    bounds = [lo] + [v for c in cuts for v in c] + [hi]
    kept = []
    for i, (a, b) in enumerate(cuts):
        left, right = (bounds[2 * i], a), (b, bounds[2 * i + 3])
        sides = [_rms(fit(*s)) if s[1] - s[0] >= SHORT else None for s in (left, right)]
        union = _rms(fit(left[0], right[1])) if None not in sides else None
        if union is None or union > SPLIT_GAIN * max(min(sides), noise):
            kept.append((a, b))
    return kept


def _jumps(x: np.ndarray, noise: float, lo: int, hi: int, SIDE: int, jump: float, guard: bool,
           parabolic: bool = False) -> np.ndarray:
    """Each frame's velocity jump in units of its noise where it is an impact (see impacts: over
    `jump`, turning round, fast either side, in its place and, with guard, at a corner), else 0.
    parabolic: only where each side's parabola misses its frames by at most PARABOLIC times the
    noise."""
    score = np.zeros(len(x))
    if hi - lo < 2 * (SIDE + GAP) + 1:
        return score
    t = np.arange(SIDE, dtype=np.float64)
    # the velocity at the frame from the SIDE frames after it (starting GAP frames on), and before it
    at_after, after = _at_zero(t + GAP)
    at_before, before = at_after[::-1], -after[::-1]
    sigma = noise * math.sqrt(float(after @ after + before @ before))
    # and the place at the frame from each side: a bounce keeps it (the thing turns round where it
    # is); a path that jumps to something else (a ball gone from view, then the ruler's flicker) does not
    sigma_at = noise * math.sqrt(float(at_after @ at_after + at_before @ at_before))
    for i in range(lo + SIDE + GAP, hi - SIDE - GAP + 1):
        va = after @ x[i + GAP:i + GAP + SIDE]
        vb = before @ x[i - GAP - SIDE + 1:i - GAP + 1]
        gap = np.abs(va - vb)
        # a bounce turns the motion round, fast either side: a release (from rest) or a swing's
        # turning point (as slow on both sides) does not
        ok = (gap > jump * sigma) & (va * vb < 0) & (np.minimum(np.abs(va), np.abs(vb)) > MOVING * sigma)
        xa = at_after @ x[i + GAP:i + GAP + SIDE]
        xb = at_before @ x[i - GAP - SIDE + 1:i - GAP + 1]
        ok &= np.abs(xa - xb) <= gap * GAP + PLACE * sigma_at  # the impact anywhere within the GAP frames
        if not ok.any() or guard and not _kinked(x[i - GAP - SIDE + 1:i + GAP + SIDE], SIDE, noise):
            continue  # no jump, or one smooth motion turns round here: no impact
        if parabolic and max(_rms(_parabola_residual(x[i - GAP - SIDE + 1:i - GAP + 1])),
                             _rms(_parabola_residual(x[i + GAP:i + GAP + SIDE]))) > PARABOLIC * noise:
            continue  # a side that is no one motion: a swing's turn read from many frames, or what
            #           the tracker took after the thing left the view
        score[i] = float((gap * ok).max()) / sigma
    return score


def _kinked(y: np.ndarray, side: int, noise: float) -> bool:
    """Whether the frames y (n, k) around a frame turn round at a corner, not smoothly: a quartic
    across them misses them by KINK times the noise, or by KINK_SHARP's times the noise and what a
    parabola fitted to each side's `side` frames misses those by."""
    smooth = _smooth_misfit(y)
    if smooth > KINK * noise:
        return True
    sides = np.concatenate([_parabola_residual(y[:side]), _parabola_residual(y[-side:])])
    return smooth > KINK_SHARP[0] * noise and smooth > KINK_SHARP[1] * float(np.sqrt(np.mean(np.square(sides))))


def _parabola_residual(y: np.ndarray) -> np.ndarray:
    t = np.arange(len(y), dtype=np.float64)
    a = np.stack([np.ones_like(t), t, t * t], axis=1)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return a @ coef - y


def _smooth_misfit(y: np.ndarray) -> float:
    """The RMS by which a quartic in time, fitted to the frames y (n, k), misses them."""
    t = np.linspace(-1.0, 1.0, len(y))
    a = np.stack([t ** p for p in range(5)], axis=1)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(np.sqrt(np.mean(np.square(a @ coef - y))))


def _at_zero(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(v, w) such that v @ y and w @ y are the value and the slope at t = 0 of the parabola
    least-squares fitted to y at times t."""
    a = np.stack([np.ones_like(t), t, t * t], axis=1)
    pinv = np.linalg.pinv(a)
    return pinv[0], pinv[1]


def find_pieces(x: np.ndarray, dt: float, fit: Callable[[int, int], np.ndarray | None], *,
                min_len: int = MIN_SEED, unread: np.ndarray | None = None, unseen: np.ndarray | None = None,
                enters: bool = False, leaves: bool = False) -> Pieces:
    """Every stretch of the path x (T, k) that one trajectory explains (see the module docstring).
    fit(a, b): the residual of one trajectory fitted to frames [a, b), or None, as find_stretch's.
    unread: True for the frames the reader did not see the object in (read from their neighbours):
    those next to an impact belong to it, not to a piece. unseen: True for the frames the reader's
    track lost the object in: a motion that ends where most of the frames after it are unseen
    leaves the view there. enters, leaves: the object enters the view at x's first frame, leaves it
    after its last (the frames before the first piece are it coming into view, not a hold to be
    released from; those after the last, it going out of view, not a stop)."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    # each fit starts from the same place, and the search asks about the same stretches again (an
    # impact's sides, then the pieces found between impacts, then their joins): 22 of 68 fits on the
    # real bouncing ball, 23 of 49 on a generated one
    fit = functools.cache(fit)
    T = len(x)
    noise_all = noise_level(x)
    rest = _still(x, at_rest(x, dt, noise_all), noise_all, dt)
    moving = np.flatnonzero(~rest)
    if len(moving) == 0:
        return Pieces([], [Event(0, "hold")], noise_all)
    lo, hi = int(moving[0]), int(moving[-1]) + 1
    noise = noise_level(x[lo:hi]) if hi - lo >= 8 else noise_all
    cuts = impacts(x, noise, lo, hi, dt)
    if unread is not None:
        cuts = _widened(cuts, np.asarray(unread, dtype=bool)[:T])
    if cuts:
        # a velocity that turns round is no impact where one trajectory explains every frame that
        # moves: a swing sampled coarsely (the paper's motion video, 16 frames a period) turns round
        # within the frames each side's velocity is read from, and was cut at every turning point
        whole = _rms(fit(lo, hi))
        if whole is not None and whole <= TOL * noise:
            cuts = []
        else:
            cuts = _felt(cuts, fit, noise, lo, hi)
    # the stretches between impacts, each searched for the part one trajectory explains (a rest
    # before the first or after the last is found there, as the single stretch finds it)
    bounds = [0] + [v for c in cuts for v in c] + [T]
    spans: list[tuple[int, int]] = []
    for a, b in zip(bounds[::2], bounds[1::2]):
        found = _parts(x, a, b, dt, fit, noise, min_len, SPLITS)
        cuts.extend((e, s) for (_, e), (s, _) in zip(found, found[1:]))  # a split is a bounce too
        spans.extend(found)
    cuts.sort()
    spans = _joined(spans, fit, noise)
    spans = _one_motion(x, spans, cuts, _side(dt))
    if len(spans) > 1:
        # a hand that holds the thing, or a thing come to rest, follows a trajectory of its own that
        # goes nowhere (a pendulum 700 m long): it is no piece of the motion
        travel = [float(np.ptp(x[a:b], axis=0).max()) for a, b in spans]
        keep = [i for i, v in enumerate(travel) if v >= HOLD_SHARE * max(travel) or 0 < i < len(spans) - 1]
        spans = [spans[i] for i in keep]
    events: list[Event] = []
    pushed = None  # where a push starts, that the first piece is cut after
    if spans and not enters and (spans[0][0] > 0 or rest[0]):
        # a release is a start: the motion leaves the held place from rest; the search may have
        # grown the first piece into the hold (a fall from rest is one trajectory with it, nearly),
        # or stopped short of the release
        a, b = spans[0]
        opening = int(np.argmin(rest)) if rest[0] else 0  # the first frame after the clip's opening rest
        r = release(x, 0, max(a, opening), b, dt)
        if r is not None and b - r >= min(min_len, SHORT) and (b - r >= min_len or _fits(fit, r, b, noise)):
            # a push is no release: where the thing left its place, but the trajectory does not
            # reach back there, or its first frames miss it, a hand moved it until the piece starts
            if r >= a or _extends(fit, r, a, b, noise):
                spans[0] = (r, b)
            else:
                pushed = r
        a = spans[0][0]
        spans[0] = (_unforced(fit, a, b, noise, _release_window(dt)), b)
        if spans[0][0] > a and pushed is None:
            pushed = a
    if spans:
        first = spans[0][0] if pushed is None else pushed
        if enters:
            events.append(Event(first, "enter"))
        elif first > 0:
            # still: at rest over most of what came before, or, a hold shorter than a rest's window
            # (a throw held 7 frames at 60 fps), flat over the frames the release was read from
            still = (rest[:first].mean() > 0.5 or _flat(x[max(first - _release_window(dt), 0):first], noise_all)
                     # or settled: a hold read to a hundredth of a pixel wanders more than its noise
                     or settled_ends(x, rest_window(dt))[0] >= first - rest_window(dt))
            events.append(Event(first, "hold" if still else "moved"))
            if pushed is not None:
                events.append(Event(spans[0][0], "push"))
            events.append(Event(spans[0][0], "release"))
        for (_, b), (a, _) in zip(spans, spans[1:]):
            hit = next((c for c in cuts if b - 1 <= c[0] and c[1] <= a + 1), None)
            events.append(Event((hit[0] + hit[1]) // 2 if hit else a, "bounce" if hit else "lost"))
        last = spans[-1][1]
        if last < T and not leaves:
            # the impact that stops it is no part of the motion either
            spans[-1] = (spans[-1][0], _unforced(fit, *spans[-1], noise, _release_window(dt), end=True))
            last = spans[-1][1]
        if leaves:
            events.append(Event(last, "gone"))
        elif last < T:
            # (a landing whose rest the clip ends too soon to show, 6 frames at 60 fps, is a stop)
            stop = rest[last:].mean() > 0.5 or (T - last <= _release_window(dt) and _flat(x[last:], noise_all))
            after = None if unseen is None else np.asarray(unseen, dtype=bool)[last:last + _release_window(dt)]
            gone = not stop and after is not None and len(after) > 0 and after.mean() > 0.5
            events.append(Event(last, "stop" if stop else "gone" if gone else "lost"))
    return Pieces(spans, events, noise)


def _parts(x: np.ndarray, a: int, b: int, dt: float, fit, noise: float, min_len: int,
           splits: int) -> list[tuple[int, int]]:
    """The stretch of frames [a, b) that one trajectory explains, found by find_stretch's search;
    where one trajectory still misses it by BREAK times the noise (a bounce too slow for impacts:
    a cart's last, short flights turn round gently), [a, b) split at its strongest turn of the
    velocity, if one trajectory each side misses by SPLIT_GAIN times less, and each side searched."""
    if b - a < min_len:
        # too short to search, but a flight between two bounces that one trajectory explains whole
        return [(a, b)] if b - a >= SHORT and _fits(fit, a, b, noise) else []
    part = find_stretch(x[a:b], dt, lambda i, j: fit(a + i, a + j), min_len=min_len, search=True)
    s, e = a + part.start, a + part.end
    whole = _rms(fit(s, e)) if e - s >= min_len else None
    if whole is None:
        return []
    if splits > 0 and whole > BREAK * noise:
        side = _side(dt)
        score = _jumps(x, noise, a, b, side, JUMP / 2, guard=False)
        i = int(np.argmax(score))
        if score[i] > 0:
            c0, c1 = i - GAP, i + GAP + 1
            sides = [_rms(fit(a, c0)) if c0 - a >= min_len else 0.0,
                     _rms(fit(c1, b)) if b - c1 >= min_len else 0.0]
            if all(v is not None and v * SPLIT_GAIN <= whole for v in sides):
                return (_parts(x, a, c0, dt, fit, noise, min_len, splits - 1)
                        + _parts(x, c1, b, dt, fit, noise, min_len, splits - 1))
    return [(s, e)]


def release(x: np.ndarray, lo: int, a: int, b: int, dt: float) -> int | None:
    """The frame a thing held still until then is let go, near the start a of the piece [a, b)
    (no earlier than lo): where the path, flat before, leaves its place as a parabola from rest
    (x = c before, c + q (t - r)^2 after: any equation's motion from rest, over a short time), or,
    where that fits THROWN times worse than with a speed of its own (c + v (t - r) + q (t - r)^2:
    a hand that throws), as that; fitted over RELEASE_S seconds either side of every candidate
    frame r (fewer before it where the clip starts sooner, RELEASE_MIN at least); the r where it
    leaves the least share of the window's spread unexplained. None where the path (its column
    of largest range) has too few frames around a."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    column = x[:, int(np.argmax(np.ptp(x[a:b], axis=0)))]
    w = _release_window(dt)
    first, last = max(lo + RELEASE_MIN, a - RELEASE_SPAN * w), min(b - w, a + RELEASE_SPAN * w)
    best = {False: (math.inf, None), True: (math.inf, None)}  # thrown: (share unexplained, frame)
    for r in range(first, last + 1):
        before = min(w, r - lo)
        y = column[r - before:r + w]
        s = np.arange(-before, w, dtype=np.float64) + 0.5  # the release between frames r - 1 and r
        after = s > 0
        spread = max(float(np.sum((y - y.mean()) ** 2)), 1e-300)
        for thrown in (False, True):
            terms = [np.ones(len(s))] + ([np.where(after, s, 0.0)] if thrown else []) + [np.where(after, s * s, 0.0)]
            basis = np.stack(terms, axis=1)
            coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
            # the share of the window's spread left unexplained: a hand's small wander fits a flat
            # line and a parabola poorly, the release of a swing's pull almost exactly
            sse = float(np.sum((basis @ coef - y) ** 2)) / spread
            if sse < best[thrown][0]:
                best[thrown] = (sse, r)
    # a throw's top is flat before and a parabola from rest after too, nearly: a 60 fps throw held
    # 7 frames was released at its top and fitted over half its flight; the speed is taken only
    # where it explains far more (a slide from rest was released a frame late with it)
    return best[True][1] if best[True][0] * THROWN < best[False][0] else best[False][1]


def _widened(cuts: list[tuple[int, int]], unread: np.ndarray) -> list[tuple[int, int]]:
    """Each impact's frames grown over the unread frames next to it: a ball that meets the floor
    blurs into its shadow in the last frames before the bounce (a real ball's centroid was 60 px off
    in two of them), and those frames, read from their neighbours across the corner, lie on neither
    flight."""
    out: list[tuple[int, int]] = []
    for a, b in cuts:
        while a > 0 and unread[a - 1]:
            a -= 1
        while b < len(unread) and unread[b]:
            b += 1
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def _still(x: np.ndarray, rest: np.ndarray, noise: float, dt: float) -> np.ndarray:
    """rest less an opening rest that drifts, over its whole length, beyond REST_SIGMAS noise
    spreads (its 2nd to 98th percentile): each short window of a slow drain is still, but a drain
    that falls 100 noise spreads over the clip is no hold (a generated one was "held still until
    4.72 s" and fitted on its last 11 frames, k 0.041 for 0.010). A closing rest stays one: a
    thing that lies still and is then slowly picked up is no motion of the equation."""
    moving = np.flatnonzero(~rest)
    end = len(x) if len(moving) == 0 else int(moving[0])
    # (a rest's last window of frames may hold the first of the motion: at_rest marks whole windows)
    held = end - (0 if len(moving) == 0 else rest_window(dt))
    if held < RELEASE_MIN:
        return rest
    lo, hi = np.percentile(x[:held], [2, 98], axis=0)
    if float(np.max(hi - lo)) <= REST_SIGMAS * noise:
        return rest
    out = rest.copy()
    out[:end] = False
    return out


def _flat(frames: np.ndarray, noise: float) -> bool:
    """At least RELEASE_MIN frames that stay within REST_SIGMAS noise spreads."""
    return len(frames) >= RELEASE_MIN and float(np.ptp(frames, axis=0).max()) <= REST_SIGMAS * noise


def _release_window(dt: float) -> int:
    """The frames each side of a release its parabola is fitted over (RELEASE_S, 4 to 40)."""
    return int(np.clip(round(RELEASE_S / dt), 4, 40))


def _side(dt: float) -> int:
    """The frames each side a velocity is read from (SIDE_S, within SIDE_FRAMES)."""
    return int(np.clip(round(SIDE_S / dt), *SIDE_FRAMES))


def _unforced(fit, a: int, b: int, noise: float, w: int, end: bool = False) -> int:
    """Where the first piece [a, b) after a hold starts once a push is left out (end: where the last
    piece, something after it, ends once the impact that stopped it is left out): a hand that pushes a puck
    or a cart starts it from rest over a few frames with a force of its own, and a block that hits
    the foot of its ramp stops within a frame or two; the search's slack for a long path's bends
    (stretch.MAIN_SLACK) grows the piece into those frames (a -2.7% on a generated puck, -0.6% on a
    block). One trajectory over the piece may miss by at most FORCED times what one misses without
    its first (last) w frames (w: a release window); where it misses by more, the piece starts
    (ends) at the first frame from which it does not (a release from rest, a swing's first turn,
    a stop by friction fit as well as what follows or comes before them)."""
    step = -1 if end else 1
    edge = b if end else a
    for k in range(w + 1):
        lo, hi = (a, edge - k) if end else (edge + k, b)
        if hi - lo < 3 * w:
            break
        with_, without = fit(lo, hi), _rms(fit(lo, hi - w) if end else fit(lo + w, hi))
        if with_ is None or without is None:
            break
        if _rms(with_) <= FORCED * max(without, noise):
            return edge + step * k
    return edge


def _extends(fit, r: int, a: int, b: int, noise: float) -> bool:
    """Whether the piece [a, b) starts as early as r: one trajectory over [r, b) misses the added
    frames [r, a) by at most TOL times the piece's own misfit (or the noise). A hand that pushes a
    puck starts it from rest as a parabola too, and the push is no part of the slide (a generated
    puck's first piece was pulled back over a 0.2 s push: a -11%)."""
    whole, own = fit(r, b), _rms(fit(a, b))
    return whole is not None and own is not None and _rms(whole[:a - r]) <= TOL * max(own, noise)


def _fits(fit, a: int, b: int, noise: float) -> bool:
    whole = _rms(fit(a, b))
    return whole is not None and whole <= TOL * noise


def _one_motion(x: np.ndarray, spans: list[tuple[int, int]], cuts: list[tuple[int, int]],
                side: int) -> list[tuple[int, int]]:
    """The run of pieces that travels farthest, where two neighbours apart by more than LOST_GAP
    velocity windows with no impact between them end one run: what the tracker follows after the
    motion was lost for that long (a ball rolled away, then a person who picks it up) is no flight."""
    runs: list[list[tuple[int, int]]] = []
    for span in spans:
        if runs:
            end = runs[-1][-1][1]
            between = np.ones(max(span[0] - end, 0), dtype=bool)
            for c0, c1 in cuts:  # the frames of the gap that no impact explains
                between[max(c0 - end, 0):max(c1 - end, 0)] = False
            if between.sum() <= LOST_GAP * (2 * side + 1):
                runs[-1].append(span)
                continue
        runs.append([span])
    if len(runs) <= 1:
        return spans
    travel = [sum(float(np.ptp(x[a:b], axis=0).max()) for a, b in run) for run in runs]
    return runs[int(np.argmax(travel))]


def _joined(spans: list[tuple[int, int]], fit, noise: float) -> list[tuple[int, int]]:
    """Neighbours that one trajectory explains as well as each alone are one piece."""
    out: list[tuple[int, int]] = []
    for span in spans:
        if out:
            a, b = out[-1]
            mine = [_rms(fit(a, b)) or math.inf, _rms(fit(*span)) or math.inf]
            union = _rms(fit(a, span[1]))
            # (the better of the two sets the bar: one that one trajectory misses badly, a slow bounce
            # inside it, made any union look as good)
            if union is not None and union <= JOIN * max(*mine, noise) and union <= TOL * max(min(mine), noise):
                out[-1] = (a, span[1])
                continue
        out.append(span)
    return out


def _rms(r: np.ndarray | None) -> float | None:
    return None if r is None or r.size == 0 else float(np.sqrt(np.mean(np.square(r))))
