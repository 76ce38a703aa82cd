"""The horizon warm-up and the motion measure of the stopping rule (train/stopping.py).

The rule's settle-then-converge sequence is tested in test_trust.py."""
from __future__ import annotations

import math

from fitode.train.config import TrainConfig
from fitode.train.history import History
from fitode.train.stopping import LOSS_FLOOR, horizon, relative_motion


def test_horizon_grows_from_a_few_frames_to_the_window():
    config = TrainConfig(window=20, horizon_warmup=100)
    lengths = [horizon(step, config, n_context=2, first=2) for step in range(0, 101)]
    assert lengths[0] == 4  # the context and two predicted frames
    assert all(a <= b for a, b in zip(lengths, lengths[1:]))
    assert lengths[-1] == 20 and lengths[99] <= 20
    assert horizon(500, config, 2, 2) == 20


def test_no_warm_up_means_the_whole_window_from_the_start():
    config = TrainConfig(window=12, horizon_warmup=0)
    assert horizon(1, config, n_context=2, first=2) == 12


def test_a_long_context_is_never_cut():
    config = TrainConfig(window=20, horizon_warmup=100)
    assert horizon(1, config, n_context=6, first=3) >= 6


def _history(values, losses) -> History:
    h = History.for_constants(["k"])
    for i, (v, loss) in enumerate(zip(values, losses), start=1):
        h.append(i, loss, loss, 0.0, {"k": v})
    return h


def test_relative_motion_reads_the_constants_and_a_tenth_of_the_loss():
    patience = 10
    assert relative_motion(_history([1.0] * 20, [1.0] * 20), patience) == math.inf  # too short to tell
    still = _history([2.0] * 30, [1.0] * 30)
    assert relative_motion(still, patience) == 0.0
    moving = _history([2.0] * 20 + [2.2] * 10, [1.0] * 30)
    assert math.isclose(relative_motion(moving, patience), 0.2 / 2.2)
    falling = _history([2.0] * 30, [1.0] * 20 + [0.5] * 10)  # the recent mean loss halves
    assert math.isclose(relative_motion(falling, patience), 0.1 * 0.5)


def test_a_tiny_loss_moves_relative_to_the_floor():
    patience = 10
    tiny = _history([2.0] * 30, [2e-6] * 20 + [1e-6] * 10)
    assert relative_motion(tiny, patience) == 0.1 * 0.5  # without a floor: the loss's own halving
    floored = relative_motion(tiny, patience, loss_floor=LOSS_FLOOR)
    assert math.isclose(floored, 0.1 * 1e-6 / LOSS_FLOOR)
