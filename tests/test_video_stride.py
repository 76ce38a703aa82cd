"""The automatic stride (fitode.stride) and its use by read_video."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fitode.stride import (FRACTION, MIN_FRAMES, STEPS_PER_PERIOD, auto_stride,
                           structure_function)
from fitode.video import read_video


def swinging_square(n: int, period: float, *, h: int = 30, w: int = 40, size: int = 6,
                    amp: float = 12.0, decay: float = 0.0, noise: float = 0.0,
                    seed: int = 0) -> np.ndarray:
    """(n, h, w) float frames of a bright square swinging left-right with the given period."""
    rng = np.random.default_rng(seed)
    out = np.zeros((n, h, w), np.float32)
    for t in range(n):
        x = w / 2 + amp * np.exp(-decay * t) * np.sin(2 * np.pi * t / period)
        x0 = int(round(x - size / 2))
        out[t, h // 2 - size // 2:h // 2 + size // 2, max(0, x0):x0 + size] = 1.0
    if noise:
        out += noise * rng.standard_normal(out.shape).astype(np.float32)
    return out


def fading(n: int, tau: float, *, h: int = 8, w: int = 8) -> np.ndarray:
    """A uniform patch whose brightness decays as exp(-t / tau): I' = -I / tau."""
    return np.exp(-np.arange(n) / tau)[:, None, None] * np.ones((1, h, w), np.float32)


def test_structure_function_matches_brute_force():
    rng = np.random.default_rng(0)
    for shape in [(2, 3), (7, 2, 3), (60, 1, 4, 5)]:
        f = rng.random(shape).astype(np.float32) + 5.0  # an offset must not cost precision
        d = structure_function(f)
        want = [np.mean((f[k:].astype(np.float64) - f[:len(f) - k]) ** 2) for k in range(len(f))]
        np.testing.assert_allclose(d, want, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("period", [32, 64, 128, 256])
def test_periodic_motion_gives_period_over_16(period):
    choice = auto_stride(swinging_square(2000, period), fps=30.0)
    assert choice.rule == "periodic"
    assert abs(choice.period - period) <= 1
    assert choice.stride == round(period / STEPS_PER_PERIOD)
    assert f"repeat every {choice.period} frames" in choice.reason


def test_period_survives_noise_and_damping():
    clean = auto_stride(swinging_square(1500, 96), fps=60.0)
    noisy = auto_stride(swinging_square(1500, 96, noise=0.2, decay=0.0005), fps=60.0)
    assert noisy.rule == "periodic" and abs(noisy.period - 96) <= 2
    assert abs(noisy.stride - clean.stride) <= 1
    assert noisy.noise > 0.1  # the frame noise was seen and removed


def test_small_fast_object_still_periodic():
    # the square (4 px) moves ~8 px per frame at the centre: pixel differences saturate at once
    choice = auto_stride(swinging_square(900, 60, size=4, amp=18.0, w=48), fps=30.0)
    assert choice.rule == "periodic" and abs(choice.period - 60) <= 1
    assert choice.stride == 4


def test_slow_change_gives_larger_stride_than_fast():
    slow = auto_stride(swinging_square(1600, 160), fps=30.0)
    fast = auto_stride(swinging_square(1600, 40), fps=30.0)
    assert slow.stride > fast.stride >= 1
    slow_fade = auto_stride(fading(600, 200.0), fps=30.0, min_frames=10)
    fast_fade = auto_stride(fading(600, 20.0), fps=30.0, min_frames=10)
    assert slow_fade.rule == fast_fade.rule == "fraction"
    assert slow_fade.stride > 3 * fast_fade.stride


def test_fraction_rule_on_a_ramp():
    n = 301
    ramp = np.linspace(0.0, 1.0, n)[:, None, None] * np.ones((1, 4, 4))
    choice = auto_stride(ramp, fps=10.0, min_frames=2)
    kmax = 2 * n // 3  # r(k) grows like k, so it reaches FRACTION of r(kmax) at FRACTION*kmax
    assert choice.rule == "fraction"
    assert abs(choice.stride - FRACTION * kmax) <= 1


def test_cap_keeps_min_frames():
    choice = auto_stride(fading(300, 1000.0), fps=30.0)
    assert choice.wanted > choice.stride == choice.cap
    assert (300 - 1) // choice.stride + 1 >= MIN_FRAMES
    assert "capped" in choice.reason


def test_still_noise_and_short_clips_get_stride_1():
    rng = np.random.default_rng(3)
    assert auto_stride(np.full((200, 5, 5), 0.3), fps=30.0).rule == "still"
    noise = auto_stride(0.5 + 0.05 * rng.standard_normal((400, 6, 6)), fps=30.0)
    assert noise.rule == "unresolved" and noise.stride == 1
    assert auto_stride(np.zeros((3, 2, 2)), fps=30.0).rule == "short"


def test_one_off_event_is_not_a_period():
    f = np.zeros((600, 10, 10), np.float32)
    f[100:160, 3:7, 3:7] = 1.0  # something enters and leaves once
    f += np.linspace(0, 0.5, 600, dtype=np.float32)[:, None, None]  # and the light drifts
    assert auto_stride(f, fps=30.0).rule == "fraction"


def _write(path: Path, frames: np.ndarray, fps: float) -> Path:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps,
                             (frames.shape[2], frames.shape[1]))
    for f in frames:
        writer.write(cv2.cvtColor((f * 255).clip(0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
    writer.release()
    return path


def test_read_video_auto_stride_slow_vs_fast(tmp_path):
    slow = read_video(_write(tmp_path / "slow.mp4", swinging_square(1000, 120), 30.0))
    fast = read_video(_write(tmp_path / "fast.mp4", swinging_square(1000, 30), 30.0))
    assert slow.stride > fast.stride
    assert slow.stride == round(120 / STEPS_PER_PERIOD) and fast.stride == 2
    assert slow.dt == pytest.approx(slow.stride / 30.0)
    # the stride is in frames: a slow-motion fps override changes dt, not the stride
    real = read_video(tmp_path / "slow.mp4", fps=120.0)
    assert real.stride == slow.stride and real.dt == pytest.approx(slow.stride / 120.0)
    assert len(slow.frames) == (1000 - 1) // slow.stride + 1
