"""Choosing the frame stride from how much the frames change.

The paper picked the stride by hand for every experiment. `auto_stride` picks it from the
preprocessed frames themselves, with one target: about `STEPS_PER_PERIOD` = 16 time steps per
period of the visible oscillation, i.e. omega*dt ~ 2*pi/16 ~ 0.39, the value of the
paper's synthetic benchmark (omega = 2, dt = 0.2), at which the method is known to work.

The measurement is the structure function of the sequence (fitode.train.motion, shared with the
training window),

    D(k) = mean over t and pixels of (f[t+k] - f[t])^2,

the mean squared change between frames k apart, for every lag k at once. Sensor and compression
noise that is independent from frame to frame adds a constant 2*sigma^2 to every D(k); it is
estimated by extrapolating D to lag 0 from D(1) and D(2) and removed, leaving the RMS change
due to motion, r(k) = sqrt(D(k) - noise). Two rules read r:

1. Periodic: if the frames come back (r dips by at least 20% between two high stretches, and
   a shallow dip recurs at twice the lag; see `_period`), the lag of that dip is the period P
   in frames, and the stride is round(P / 16). This rule does not care how the pixel
   difference saturates: a small object that moves by more than its own size makes r plateau
   early, but the frames still come back after one period.
2. Otherwise (decays, drifts, free fall): the stride is the smallest lag at which r reaches
   sin(pi/16) ~ 0.195 of its largest value R over lags up to 2N/3. For a signal that varies
   like a sinusoid this is exactly rule 1 (r(k) ~ |sin(pi k / P)|); for a monotone change it
   asks that one step moves the frames by about a fifth of the full range. When the change
   saturates early this errs towards a smaller stride, the safe side.

Both are then capped so that at least `min_frames` frames remain (100 by default: five
windows of 20 frames) and the stride is at least 1. If the frames do not change at all, or
change about as much between neighbours as over the whole clip (pure noise, or motion too fast
for the frame rate), the stride is 1.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fitode.train.motion import motion_rms, search_lags, structure_function

STEPS_PER_PERIOD = 16
FRACTION = math.sin(math.pi / STEPS_PER_PERIOD)  # ~0.195: rule 2's share of the full change
MIN_FRAMES = 100
DIP = 0.2  # how far (as a share) the change must fall back for the frames to count as repeating


@dataclass
class StrideChoice:
    """What `auto_stride` chose and from which numbers."""

    stride: int
    reason: str            # one sentence with the numbers
    rule: str              # "periodic" | "fraction" | "still" | "unresolved" | "short"
    wanted: int            # the rule's stride before the cap
    cap: int               # the largest stride that keeps `min_frames` frames
    period: int | None     # frames per period when the rule is "periodic"
    change: float          # R: the largest RMS change due to motion (0..1 units)
    noise: float           # RMS frame-to-frame noise removed from the changes


def auto_stride(frames: np.ndarray, fps: float, *, min_frames: int = MIN_FRAMES) -> StrideChoice:
    """Pick the stride for `frames` (N, ...) sampled at `fps`. See the module docstring."""
    n = int(frames.shape[0])
    cap = max(1, (n - 1) // max(1, min_frames - 1))
    if n < 4:
        return StrideChoice(1, f"auto: only {n} frame(s), so stride 1", "short", 1, cap, None,
                            0.0, 0.0)
    d = structure_function(frames)
    kmax = search_lags(n)
    top = float(d[1:kmax + 1].max())
    if top <= 1e-12:
        return StrideChoice(1, "auto: the frames do not change at all, so stride 1", "still", 1,
                            cap, None, 0.0, 0.0)
    if top <= 1.2 * d[1]:
        return StrideChoice(1, ("auto: neighbouring frames differ about as much as frames far "
                                "apart (noise, or motion too fast for the frame rate), so stride 1"),
                            "unresolved", 1, cap, None, math.sqrt(top), math.sqrt(d[1]))
    # Lags up to 2N/3 set the scale and are searched; longer ones, with fewer pairs, only confirm a period.
    r_all, noise = motion_rms(d, max(kmax, n - 5))
    r = r_all[:kmax]
    big = float(r.max())

    period = _period(r_all, kmax)
    if period is not None:
        rule, want = "periodic", max(1, round(period / STEPS_PER_PERIOD))
        why = (f"the frames repeat every {period} frames ({period / fps:.3g} s), "
               f"and {STEPS_PER_PERIOD} steps per period give stride {want}")
    else:
        rule, want = "fraction", int(np.argmax(r >= FRACTION * big)) + 1
        why = (f"the RMS frame change reaches {FRACTION:.2f} of its largest value "
               f"({FRACTION * big:.3g} of {big:.3g}) at a lag of {want} frame{'s' * (want > 1)}")
    stride = min(want, cap)
    kept = (n - 1) // stride + 1
    tail = f", capped at {cap} to keep at least {min_frames} frames" if stride < want else ""
    return StrideChoice(stride, f"auto: {why}{tail}; {kept} frames at dt {stride / fps:.4g} s",
                        rule, want, cap, period, big, math.sqrt(noise))


def _period(r: np.ndarray, search: int) -> int | None:
    """The lag (frames) at which the frames first come back, or None if they never do.

    `r[i]` is the motion's RMS change at lag i+1. A return is a local minimum of r among the
    first `search` lags that lies at least `DIP` below the lower of the highest r before it
    and the highest r after it, where both of those are at least half of the largest r (so
    small wiggles on a plateau do not count). A shallow dip (less than half-way down) must be
    confirmed by another within 10% of twice its lag: a one-off event (a hand that enters and
    leaves) or a slow drift does not repeat. Fast objects make dips shallow: a bob that moves
    a good part of its own size per frame never matches a frame exactly one period later.
    """
    big = float(r[:search].max())
    for i in range(1, min(search, len(r) - 1)):
        if not (r[i] <= r[i - 1] and r[i] < r[i + 1]):
            continue
        top = min(float(r[:i].max()), float(r[i:].max()))
        if top < 0.5 * big or r[i] > (1.0 - DIP) * top:
            continue
        lag = i + 1
        if r[i] <= 0.5 * top:
            return lag
        tol = max(1, lag // 10)
        lo, hi = 2 * lag - 1 - tol, 2 * lag - 1 + tol + 1
        if hi + 1 >= len(r):
            return None  # too short to confirm a shallow dip
        j = lo + int(np.argmin(r[lo:hi]))
        if lo < j < hi - 1 and r[j] <= (1.0 - DIP) * top:
            return lag
    return None
