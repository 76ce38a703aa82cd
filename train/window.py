"""The training window's length, chosen in time so that a window sees the dynamics bend.

A window too short for the dynamics cannot tell their rate: a decay with a 1.1 s time constant
is nearly a straight line over 20 frames at 30 fps (0.67 s), and restarts then settle anywhere
along it with losses near zero. The stride (fitode.stride) already spaces the frames so that a
step changes them by a fair share, but it is capped to keep 100 frames, and a short clip of a
slow decay keeps stride 1.

So the window is measured from the same structure function as the stride: r(k), the RMS change
of the frames between lags k apart (noise removed), reaches SHARE = 1 - 1/e of its largest value
at a lag of about one time constant of a decay (r(k) ~ 1 - exp(-k dt / tau)) and a fifth of a
period of an oscillation. The window spans at least that lag, and at least WINDOW_MIN frames
(the paper's 20: over a period of a 16-steps-per-period oscillation); at most the training
frames less one, which makes one window the whole clip (multiple shooting with one shot).
`--window N` fixes it.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import torch

from .motion import motion_rms, search_lags, structure_function

WINDOW_MIN = 20
SHARE = 1 - 1 / math.e


def auto_window(frames: np.ndarray, dt: float) -> tuple[int, str]:
    """The window (frames) for training on frames (T, ...) spaced dt apart, and why."""
    n = int(frames.shape[0])
    top = max(n - 1, 2)
    if n < 4:
        return top, f"auto: the whole clip ({n} frames)"
    d = structure_function(frames)
    r, _ = motion_rms(d, search_lags(n))
    if float(r.max()) <= 0:
        window = min(WINDOW_MIN, top)
        return window, f"auto: {window} frames ({window * dt:.3g} s); the frames do not change"
    lag = int(np.argmax(r >= SHARE * float(r.max()))) + 1
    want = max(WINDOW_MIN, lag + 1)
    window = min(want, top)
    why = (f"the frames' RMS change reaches {SHARE:.0%} of its largest at a lag of {lag} frame{'s' * (lag > 1)} "
           f"({lag * dt:.3g} s: about a time constant, or a fifth of a period)")
    if want > top:
        how = "more than the clip has: one window spans the whole clip"
    elif lag + 1 > WINDOW_MIN:
        how = "so a window spans it"
    else:
        how = f"within the least window, {WINDOW_MIN} frames"
    return window, f"auto: {window} frames ({window * dt:.3g} s); {why}, {how}"


def resolve_window(config, frames: torch.Tensor | np.ndarray, dt: float):
    """config with its window set (auto_window where it is None), and the reason printed for it."""
    if config.window is not None:
        return config, f"{config.window} frames ({config.window * dt:.3g} s; as asked)"
    x = frames.detach().cpu().numpy() if isinstance(frames, torch.Tensor) else np.asarray(frames)
    window, reason = auto_window(x.astype(np.float32, copy=False), dt)
    return replace(config, window=window), reason
