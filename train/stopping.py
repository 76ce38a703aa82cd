"""When a run has settled: the horizon warm-up and the stopping rule.

A run is checked every `check_every` steps once it is past min_steps and the horizon warm-up.
When the largest relative change over the last `patience` steps of any constant (or a tenth of
the mean loss's, measured against a floor of LOSS_FLOOR) falls below 10*tol, the run is close: its learning rates drop by
settle_factor so the constants settle precisely. Once it has been close for `patience` steps
and the motion is below tol, it has converged and stops.
"""
from __future__ import annotations

import math

import numpy as np

from .config import TrainConfig
from .history import History


def horizon(step: int, config: TrainConfig, n_context: int, first: int) -> int:
    """Frames per window at this step: a few predicted frames at first, the whole window after warm-up.

    Far from the true constants a 20-frame rollout can grow by many orders of magnitude, and its
    error then drowns both the gradient of the constants and the KL term that keeps the encoder
    alive. Short rollouts first let the constants approach the data before the horizon grows.
    """
    shortest = max(n_context, first + 2)
    if config.horizon_warmup <= 0 or step >= config.horizon_warmup:
        return config.window
    frac = step / config.horizon_warmup
    return min(config.window, shortest + int(frac * (config.window - shortest + 1)))


# Below this loss (in units of the prior's variance: a window miss under 1% of the latent's
# spread) the loss's relative wobble is the encoder polishing noise, not progress: changes are
# measured against this floor, so a run whose constants have settled is not kept going by it.
LOSS_FLOOR = 1e-4


def relative_motion(hist: History, patience: int, loss_floor: float = 0.0) -> float:
    """Largest relative change, over the last `patience` steps, of any constant or of the mean loss
    (the loss's change relative to its value, or to loss_floor where the loss lies below it)."""
    if len(hist) <= 2 * patience:
        return math.inf
    worst = 0.0
    for series in hist.constants.values():
        now, then = series[-1], series[-1 - patience]
        worst = max(worst, abs(now - then) / max(abs(now), 1e-3))
    recent = float(np.mean(hist.loss[-patience:]))
    before = float(np.mean(hist.loss[-2 * patience: -patience]))
    return max(worst, 0.1 * abs(recent - before) / max(abs(before), loss_floor, 1e-12))


class StopRule:
    """The stopping rule of one run; `update` says "settle", "converged" or None."""

    def __init__(self, config: TrainConfig):
        self.config = config
        self.settled_at: int | None = None

    def update(self, step: int, hist: History) -> str | None:
        c = self.config
        if step < max(c.min_steps, c.horizon_warmup):
            return None
        moving = relative_motion(hist, c.patience, LOSS_FLOOR * c.prior[1] ** 2)
        if self.settled_at is None:
            if moving < c.tol * 10:
                self.settled_at = step
                return "settle"
            return None
        if step - self.settled_at >= c.patience and moving < c.tol:
            return "converged"
        return None
