"""When each frame was taken: the container's timestamps, checked, with repeated frames dropped.

A container's nominal frame rate is a promise the file does not always keep:
- a clip converted from 24 to 30 fps by pulldown repeats every fifth frame, and a stalled
  encoder writes duplicates: each repeat is a step in every measured path;
- a phone writes a variable frame rate: its timestamps are the capture times, jittered around
  the nominal interval, with a gap where it dropped a frame;
- an edit list or a long last frame pulls the nominal rate off the timestamps' own.

`frame_times` reads the timestamps of the frames read and returns what the fit should use.
The fit itself runs on a uniform grid (windows, rollouts and trajectories all take one dt), so
real times are met here, once, and the fit gets a uniform grid at the real rate:
- stamps at a constant rate other than the nominal one: that rate;
- stamps that jitter around a constant capture rate, with holes where frames were dropped (a
  phone): each frame on its nearest grid point (the jitter, random, is left), each hole filled
  with a blend of the two frames around it. Frames are not blended onto the grid wholesale: a
  blend of a moving thing is two faint copies, which a learned encoder does not read as the
  position midway (a damping rate came out 15% low that way);
- frames repeated by a rate conversion are dropped with their times; what remains came from a
  constant-rate source whose true times are a uniform grid (the converted file's stamps are the
  output grid's, up to half an output interval off the capture), at 24 of every 30;
- stamps that follow no constant rate: every frame resampled onto a uniform grid at the real
  mean rate, each a blend of the two frames around its time.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

REPEAT_SHARE = 0.2      # a frame is a repeat when it differs from the one before by less than this share
#                         of the typical difference between its neighbours (its motion plus noise)
NEIGHBOURS = 6          # frames either side that define the typical difference
MOVING = 3.0            # ... and only where that typical difference stands this far above the clip's noise
#                         floor: in a still stretch a repeat carries nothing and nothing tells it apart
MIN_CHANGE = 4 / 255    # ... and above a few levels of 8-bit video: a slow fade changes a level every few
#                         frames, and the frames between are equal without being repeats
IRREGULAR = 0.05        # timestamps farther than this share of an interval from a uniform grid are irregular
SLOT_SLACK = 0.45       # ... and up to this far, each still belongs to one point of a grid at a constant rate
CONVERSION_SLACK = 0.5  # after a rate conversion, stamps may sit up to half an interval off the capture
CONVERSION_REPEATS = 3  # fewer repeats than this are no rate conversion (a still pair at a turning point
#                         looks like one): their times are kept and the rest resampled where irregular
TURN_SPAN = 3           # frames over which the motion into and out of a still pair is read (_turns)
SLOW_MOTION = (2, 4, 8, 16)  # factors a phone or camera records slow motion at (60/120/240/480 played at 30)


@dataclass
class FrameTimes:
    """What the fit uses of the frames read: `keep` (indices of the frames read), then, when
    `grid` is not None, those frames resampled at the times `grid` (seconds); `rate` is the real
    frame rate of the result (1 / its interval); `lines` say what was done, for the header."""

    keep: np.ndarray
    rate: float
    grid: np.ndarray | None = None
    stamps: np.ndarray | None = None  # the real times of the kept frames, before any resampling
    repeats: int = 0
    lines: list[str] = field(default_factory=list)


def frame_differences(frames: np.ndarray) -> np.ndarray:
    """Largest absolute difference of each frame from the one before (length T - 1), in the
    frames' units ([0, 1]): a small moving thing changes few pixels, but those by its contrast."""
    f = np.asarray(frames, np.float32).reshape(len(frames), -1)
    return np.abs(np.diff(f, axis=0)).max(axis=1) if len(f) > 1 else np.zeros(0)


def repeated_frames(frames: np.ndarray) -> np.ndarray:
    """Which frames repeat the frame before (bool, length T).

    A repeat differs from the frame before by far less than the neighbouring pairs do (codec
    noise only, against motion plus the sensor's noise), where those stand clearly above the
    clip's noise floor (the lower decile of all differences), and the pairs just before and
    after it move as much as the others, the same way (_turns): at a swing's turning point or a
    bounce two frames taken either side of the turn also look alike, but the thing came back. Where the
    repeats come at a fixed period (a rate conversion: every fifth frame from 24 to 30 fps), every
    frame at that period whose difference sits at the noise floor is one (turning points
    included), and no other (where nothing moves a repeat carries nothing, so dropping it costs nothing)."""
    d = frame_differences(frames)
    out = np.zeros(len(frames), bool)
    if len(d) < 3:
        return out
    floor = float(np.quantile(d, 0.1))
    typical = np.empty(len(d))
    for i in range(len(d)):
        lo, hi = max(0, i - NEIGHBOURS), min(len(d), i + NEIGHBOURS + 1)
        typical[i] = float(np.median(np.delete(d[lo:hi], i - lo)))
    for i in range(1, len(d) - 1):
        moving = typical[i] > MOVING * floor and typical[i] > MIN_CHANGE
        if moving and d[i] < REPEAT_SHARE * typical[i] and min(d[i - 1], d[i + 1]) >= 0.5 * typical[i] \
                and not _turns(frames, i + 1):
            out[i + 1] = True
    idx = np.flatnonzero(out)
    if len(idx) >= CONVERSION_REPEATS:
        values, counts = np.unique(np.diff(idx), return_counts=True)
        period = int(values[counts.argmax()])
        if period >= 2 and counts.max() >= 0.6 * (len(idx) - 1):
            # a conversion repeats at its period and nowhere else: a still pair off the period is motion
            phase = np.bincount(idx % period, minlength=period).argmax()
            out[:] = False
            for j in range(int(phase) or period, len(frames), period):
                if d[j - 1] < REPEAT_SHARE * typical[j - 1] or d[j - 1] <= 2 * floor:
                    out[j] = True
    return out


def _turns(frames: np.ndarray, j: int) -> bool:
    """Does the motion turn round between frames j - 1 and j (a swing's turning point, a bounce)?
    Then the two look alike because the thing came back, not because one repeats the other: the
    motion into frame j - 1 and out of frame j go opposite ways, where a repeat inside a motion
    leaves both going the same way. Each is read over TURN_SPAN frames apart from the pair (to
    j - 2, from j + 1), as the way from where the change darkens to where it brightens (_way)."""
    if j < 2 + TURN_SPAN or j + 1 + TURN_SPAN >= len(frames):
        return False
    into = _way(np.asarray(frames[j - 2], np.float32) - np.asarray(frames[j - 2 - TURN_SPAN], np.float32))
    out = _way(np.asarray(frames[j + 1 + TURN_SPAN], np.float32) - np.asarray(frames[j + 1], np.float32))
    return into is not None and out is not None and float(into @ out) < 0.0


def _way(change: np.ndarray) -> np.ndarray | None:
    """The image vector (row, column) from the centroid of where a change darkens to where it
    brightens, on the pixels that change most (a moving thing's two edges); None where one is missing."""
    c = np.squeeze(change)
    if c.ndim == 3:  # colour, channels first or last: the smallest axis
        c = c.mean(axis=int(np.argmin(c.shape)))
    if c.ndim != 2:
        return None
    level = 0.3 * float(np.abs(c).max())
    if not level > 0:
        return None
    rows, cols = np.indices(c.shape)
    ends = []
    for part in (np.where(c > level, c, 0.0), np.where(c < -level, -c, 0.0)):
        total = float(part.sum())
        if total <= 0:
            return None
        ends.append(np.array([float((part * rows).sum()), float((part * cols).sum())]) / total)
    return ends[0] - ends[1]


def uniform_fit(stamps: np.ndarray) -> tuple[float, float, float]:
    """The uniform grid closest to the stamps (least squares of time on index): its first time,
    its interval, and the largest distance of a stamp from it, as a share of the interval."""
    i = np.arange(len(stamps), dtype=np.float64)
    step, start = np.polyfit(i, stamps, 1)
    worst = float(np.abs(stamps - (start + step * i)).max()) / step
    return float(start), float(step), worst


def frame_times(frames: np.ndarray, stamps: np.ndarray | None, rate: float, *, consecutive: bool = True) -> FrameTimes:
    """What the fit should use of `frames` (T, ...) read at `stamps` (seconds, None: the source
    has none, a folder or an array), given the nominal `rate`.

    consecutive: the frames are every frame of the source range (repeats can only be told then)."""
    n = len(frames)
    everything = np.arange(n)
    if stamps is None or n < 3:
        return FrameTimes(everything, rate)
    t = np.asarray(stamps, np.float64)
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        return FrameTimes(everything, rate, lines=["the container's timestamps do not increase: the nominal rate is "
                                                   "used"])
    lines: list[str] = []
    repeat = repeated_frames(frames) if consecutive else np.zeros(n, bool)
    keep = everything[~repeat]
    kt = t[keep]
    _, step, worst = uniform_fit(kt)
    real = 1.0 / step
    if repeat.any():
        k = int(repeat.sum())
        lines.append(f"{k} repeated frame{'s' if k > 1 else ''} dropped (a frame that repeats the one before: "
                     f"{_pattern(np.flatnonzero(repeat))}), with {'their times' if k > 1 else 'its time'}")
        if k >= CONVERSION_REPEATS and worst <= CONVERSION_SLACK:
            # a rate conversion: what remains was taken at a constant rate; the stamps are the output grid's,
            # so its rate is the share kept of the output's (24 of every 30)
            real = len(keep) / (n * uniform_fit(t)[1])
            lines.append(f"the remaining {len(keep)} frames were taken at a constant {real:.6g} fps (a rate "
                         "conversion's stamps are its output grid, not the capture times)")
            return FrameTimes(keep, real, stamps=kt[0] + np.arange(len(keep)) / real, repeats=k, lines=lines)
    if worst <= IRREGULAR:
        if abs(real / rate - 1) <= 1e-4:
            return FrameTimes(keep, rate, stamps=kt, repeats=int(repeat.sum()), lines=lines)
        lines.append(f"the timestamps run at {real:.6g} fps, not the nominal {rate:.6g}: {real:.6g} is used")
        return FrameTimes(keep, real, stamps=kt, repeats=int(repeat.sum()), lines=lines)
    # each interval in whole capture intervals (1, or 2 across a dropped frame), then the grid fitted to them
    slots = np.r_[0.0, np.cumsum(np.maximum(1.0, np.rint(np.diff(kt) / np.median(np.diff(kt)))))]
    if len(kt) >= 3:
        # a constant capture rate with jitter and holes (a phone): each frame on its nearest grid point,
        # the holes (dropped frames) filled in. Frames are not blended onto the grid: a blend of a moving
        # thing is two faint copies, which a learned encoder does not read as the midway position.
        step, start = np.polyfit(slots, kt, 1)
        slots = np.rint((kt - start) / step)  # again, from the fitted grid rather than from each neighbour
        slots -= slots[0]
        step, start = np.polyfit(slots, kt, 1)
        snapped = start + step * slots
        off = (kt - snapped) / step
        start = kt[0]  # the grid through the first frame's own time: only differences matter to the fit
        snapped = start + step * slots
        if np.abs(off).max() <= SLOT_SLACK and np.all(np.diff(slots) >= 1):
            n_slots = int(slots[-1]) + 1
            grid = start + step * np.arange(n_slots)
            gaps = int(np.sum(np.diff(slots) > 1))
            if np.abs(off).max() > IRREGULAR:
                lines.append(f"the timestamps jitter around a constant {1 / step:.6g} fps (rms {np.sqrt(np.mean(off ** 2)):.2f}, "
                             f"at most {np.abs(off).max():.2f} of an interval): each frame is kept on its nearest point of "
                             "that grid")
            elif abs(step * rate - 1) > 1e-4:
                lines.append(f"the timestamps run at {1 / step:.6g} fps, not the nominal {rate:.6g}: {1 / step:.6g} is used")
            if gaps:
                lines.append(f"{gaps} gap{'s' if gaps > 1 else ''} in the timestamps ({n_slots - len(kt)} dropped "
                             f"frame{'s' if n_slots - len(kt) > 1 else ''}): each missing frame filled in as a blend of "
                             "the two around it")
            return FrameTimes(keep, 1 / step, grid=grid if gaps else None, stamps=snapped if gaps else kt,
                              repeats=int(repeat.sum()), lines=lines)
    step = (kt[-1] - kt[0]) / (len(kt) - 1)  # the mean interval: as many frames as were taken, over the same span
    real = 1.0 / step
    grid = kt[0] + step * np.arange(len(kt))
    lines.append(f"variable frame rate: the timestamps stray up to {worst:.2f} of an interval from a uniform grid; "
                 f"the frames were resampled onto a uniform grid at the real mean rate, {real:.6g} fps (each a blend "
                 "of the two frames around its time)")
    return FrameTimes(keep, real, grid=grid, stamps=kt, repeats=int(repeat.sum()), lines=lines)


def resample(frames: np.ndarray, times: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Frames at the times `grid`, each the linear blend of the two frames around it."""
    j = np.clip(np.searchsorted(times, grid, side="right") - 1, 0, len(times) - 2)
    w = ((grid - times[j]) / (times[j + 1] - times[j])).clip(0.0, 1.0).astype(np.float32)
    shape = (-1,) + (1,) * (frames.ndim - 1)
    return (1 - w).reshape(shape) * frames[j] + w.reshape(shape) * frames[j + 1]


def slow_motion_factor(expected: float, got: float, tolerance: float = 0.15) -> int | None:
    """The common slow-motion factor k whose square is expected / got (within `tolerance`): a
    clip played at 1/k of its capture rate makes an acceleration k^2 too small."""
    if not (expected > 0 and got > 0):
        return None
    ratio = expected / got
    for k in SLOW_MOTION:
        if abs(ratio / k**2 - 1) <= tolerance:
            return k
    return None


def slow_motion_hint(known: dict[str, float], estimates: dict[str, float], fps: float) -> list[str]:
    """Lines for constants the equation knows (g) that came out about k^2 too small for a common
    slow-motion factor k: which --fps would make them right. estimates: the values in physical
    units (calibrated, or measured in their own units) by name."""
    lines = []
    for name, value in estimates.items():
        k = slow_motion_factor(known[name], value) if name in known else None
        if k:
            lines.append(f"hint: {name} came out {value:.4g}, about 1/{k * k} of the known {known[name]:.6g}: a clip "
                         f"recorded at {k}x slow motion does that; if this one was, pass --fps {k * fps:.6g}")
    return lines


def _pattern(idx: np.ndarray) -> str:
    if len(idx) >= 3:
        gaps = np.diff(idx)
        if np.all(gaps == gaps[0]):
            return f"every {int(gaps[0])}th frame, from frame {int(idx[0])}"
        values, counts = np.unique(gaps, return_counts=True)
        if counts.max() >= 0.6 * len(gaps):
            return f"mostly every {int(values[counts.argmax()])}th frame, first at frame {int(idx[0])}"
    return "frame" + ("s " if len(idx) > 1 else " ") + ", ".join(str(int(i)) for i in idx[:8]) + (
        ", ..." if len(idx) > 8 else "")
