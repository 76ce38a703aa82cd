"""The training window chosen in time (train/window.py)."""
from __future__ import annotations

import numpy as np

from fitode.train.config import TrainConfig
from fitode.train.window import WINDOW_MIN, auto_window, resolve_window


def _patch(values: np.ndarray, noise: float = 0.005, seed: int = 0) -> np.ndarray:
    """A 12x12 patch whose brightness follows values, on a textured noisy background."""
    rng = np.random.default_rng(seed)
    wall = 0.3 + 0.05 * rng.random((24, 24))
    out = np.repeat(wall[None], len(values), axis=0)
    out[:, 6:18, 6:18] += 0.5 * values[:, None, None]
    return (out + noise * rng.standard_normal(out.shape)).astype(np.float32)


def test_a_slow_decay_gets_a_window_of_about_one_time_constant():
    dt, tau = 1 / 60, 1.2  # 3 s at 60 fps: 20 frames would see a third of a time constant
    t = np.arange(180) * dt
    window, reason = auto_window(_patch(np.exp(-t / tau)), dt)
    assert 0.7 * tau / dt < window < 1.3 * tau / dt, (window, reason)
    assert "about a time constant" in reason and "so a window spans it" in reason


def test_an_oscillation_keeps_the_least_window_and_a_short_clip_is_one_window():
    dt = 1 / 30
    t = np.arange(300) * dt
    window, reason = auto_window(_patch(0.5 + 0.5 * np.sin(2 * np.pi * t / 1.0)), dt)  # 30 frames a period
    assert window == WINDOW_MIN and "within the least window" in reason
    window, reason = auto_window(_patch(np.exp(-np.arange(15) * dt / 5.0)), dt)
    assert window == 14 and "whole clip" in reason


def test_a_window_given_is_kept():
    frames = _patch(np.linspace(1, 0, 50))
    config, reason = resolve_window(TrainConfig(window=12), frames, 0.1)
    assert config.window == 12 and "as asked" in reason
    config, reason = resolve_window(TrainConfig(), frames, 0.1)
    assert config.window >= WINDOW_MIN and reason.startswith("auto:")
