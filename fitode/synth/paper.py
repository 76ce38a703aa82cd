"""The paper's three synthetic datasets (arXiv 2410.01376, section 5.1), and the same three
renderings of any signal.

Conventions, checked against the authors' data generator (github.com/Alejandro-neuro/Vphy,
Data/genData.py and Figures/init_exp.py) where it shows them:
- dynamics: z(t) = e^{-0.04 t} cos(2 t), i.e. z'' + g1 z' + g0 z = 0 with g0 = 4.0016,
  g1 = 0.08, z(0) = 1, z'(0) = -0.04; they simulate t in [0, 54) at 0.01 s and feed frames
  20 samples apart (dt = 0.2). Default here: 270 frames at dt = 0.2 (the same 54 s). Pass
  dt=0.01, n_frames=5400 for their sample density.
- motion: a pendulum hanging from the frame centre, rod 20 px (grey, 2 px wide), bob of
  radius 3 px (white), angle = z times a fixed span. Their code used angle = 180 deg * z with
  z in [-0.5, 0.5] (+-90 deg); the issue asks for about +-120 deg, so here angle = 120 deg * z
  (max_angle). Positive angles swing to the right.
- intensity: a fixed irregular shape on black whose gray level is 0.6 + 0.4 z, so z in
  [-1, 1] spans [0.2, 1.0] (their generateDynamics(max=1, min=0.2)). Their shape was a
  thresholded neuron picture; ours is a seeded smooth star-shaped blob.
- scale: a centred circle of base radius 10 px whose left half has radius 10 (1 + z) and
  right half 10 (1 - z) px (their create_half_radius_circle_image with X = 10 z): one half
  grows while the other shrinks.
Every length scales with size / 50. Frames are float32 in [0, 1], drawn at 4x supersampling.
"""
from __future__ import annotations

import numpy as np

from fitode.errors import FitodeError
from fitode.synth import render as R
from fitode.synth.trajectory import damped_oscillator
from fitode.synth.video import SynthVideo

PAPER_KINDS = ("motion", "intensity", "scale")
MODES = PAPER_KINDS

# geometry as fractions of the frame size (50 px in the paper)
PENDULUM_LENGTH = 0.4      # 20 px
BOB_RADIUS = 0.06          # 3 px
ROD_HALF_WIDTH = 0.02      # 2 px wide
ROD_GRAY = 0.5
BLOB_RADIUS = 0.3          # mean radius of the irregular shape, 15 px
SCALE_RADIUS = 0.2         # 10 px
GRAY_MID, GRAY_AMP = 0.6, 0.4


def paper_video(kind: str = "intensity", *, n_frames: int = 270, dt: float = 0.2, size: int = 50,
                seed: int = 0, g0: float = 4.0016, g1: float = 0.08, z0: float = 1.0,
                v0: float | None = None, noise: float = 0.0, max_angle: float = 120.0,
                ss: int = 4) -> SynthVideo:
    """One of the paper's synthetic videos of z'' + g1 z' + g0 z = 0 (exact closed form).

    kind: "motion" (pendulum angle = max_angle * z degrees), "intensity" (gray level
    0.6 + 0.4 z) or "scale" (half radii 0.2 size (1 +- z)).
    v0 = None means z'(0) = -g1/2 * z0, which makes z = z0 e^{-g1 t/2} cos(w t) (the paper's).
    noise: standard deviation of additive Gaussian pixel noise (0: clean, as the paper).
    seed: the irregular shape (intensity) and the noise.
    """
    _check_common(kind, n_frames, dt, size, ss)
    if v0 is None:
        v0 = -0.5 * g1 * z0
    t = np.arange(n_frames) * dt
    z, zdot = damped_oscillator(t, g0, g1, z0, v0)
    frames = render_signal(z, kind, size=size, seed=seed, max_angle=max_angle, ss=ss, noise=noise)
    meta = {
        "generator": "paper", "kind": kind, "system": "damped_oscillator", "seed": seed, "size": size, "n_frames": n_frames,
        "dt": dt, "z0": z0, "v0": v0, "noise": noise, "supersampling": ss,
        "mapping": mapping_text(kind, max_angle),
    }
    return SynthVideo(frames=frames, dt=float(dt), truth={"g0": float(g0), "g1": float(g1)},
                      latent=z[:, None], equation="z'' + g1*z' + g0*z = 0", latent_names=("z",),
                      state=np.stack([z, zdot], axis=1), state_names=("z", "z'"), meta=meta)


def mapping_text(mode: str, max_angle: float = 120.0) -> str:
    return {
        "motion": f"pendulum angle = {max_angle:g} deg * u (pivot at the centre, 0 = hanging down)",
        "intensity": f"gray level of an irregular shape = {GRAY_MID} + {GRAY_AMP} * u",
        "scale": f"left half radius = {SCALE_RADIUS:g} * size * (1 + u), "
                 f"right half = {SCALE_RADIUS:g} * size * (1 - u)",
    }[mode]


def _check_common(mode: str, n_frames: int, dt: float, size: int, ss: int) -> None:
    if mode not in MODES:
        raise FitodeError(f"unknown rendering '{mode}': choose one of {', '.join(MODES)}")
    if int(n_frames) < 2:
        raise FitodeError(f"need at least 2 frames, got {n_frames}")
    if not (dt > 0 and np.isfinite(dt)):
        raise FitodeError(f"dt must be a positive number of seconds, got {dt}")
    if not 8 <= int(size) <= 1024:
        raise FitodeError(f"size must be between 8 and 1024 pixels, got {size}")
    if not 1 <= int(ss) <= 16:
        raise FitodeError(f"supersampling must be between 1 and 16, got {ss}")


def render_signal(u: np.ndarray, mode: str, *, size: int = 50, seed: int = 0,
                  max_angle: float = 120.0, ss: int = 4, noise: float = 0.0) -> np.ndarray:
    """Frames (T, size, size) float32 in [0, 1] showing the series u in one of the paper's ways."""
    u = np.asarray(u, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(u)):
        raise FitodeError("the signal to render is not finite")
    n = len(u)
    if mode == "intensity":
        cov = shape_coverage(size, seed, ss)
        gray = np.clip(GRAY_MID + GRAY_AMP * u, 0.0, 1.0).astype(np.float32)
        frames = gray[:, None, None] * cov[None]
    elif mode == "motion":
        frames = np.empty((n, size, size), np.float32)
        for i, ui in enumerate(u):
            frames[i] = pendulum_frame(np.deg2rad(max_angle * ui), size, ss)
    elif mode == "scale":
        frames = np.empty((n, size, size), np.float32)
        for i, ui in enumerate(u):
            frames[i] = scale_frame(ui, size, ss)
    else:
        raise FitodeError(f"unknown rendering '{mode}': choose one of {', '.join(MODES)}")
    if noise > 0:
        rng = np.random.default_rng([int(seed), 1])
        frames = np.clip(frames + rng.normal(0.0, noise, frames.shape).astype(np.float32), 0, 1)
    return frames


def pendulum_frame(angle: float, size: int, ss: int = 4) -> np.ndarray:
    c = size / 2.0
    length, rb, hw = PENDULUM_LENGTH * size, BOB_RADIUS * size, ROD_HALF_WIDTH * size
    bx, by = c + length * np.sin(angle), c + length * np.cos(angle)
    cv = R.Canvas(np.zeros((size, size), np.float32), ss)
    cv.paint(R.segment(c, c, bx, by, hw), ROD_GRAY,
             (min(c, bx) - hw, min(c, by) - hw, max(c, bx) + hw, max(c, by) + hw))
    cv.paint(R.circle(bx, by, rb), 1.0, (bx - rb, by - rb, bx + rb, by + rb))
    return cv.image


def scale_frame(u: float, size: int, ss: int = 4) -> np.ndarray:
    c = size / 2.0
    r0 = SCALE_RADIUS * size
    rl, rr = max(r0 * (1 + u), 0.0), max(r0 * (1 - u), 0.0)
    cv = R.Canvas(np.zeros((size, size), np.float32), ss)
    if rl > 0:
        cv.paint(R.intersect(R.circle(c, c, rl), R.half_plane(1, 0, c, c)), 1.0,
                 (c - rl, c - rl, c, c + rl))
    if rr > 0:
        cv.paint(R.intersect(R.circle(c, c, rr), R.half_plane(-1, 0, c, c)), 1.0,
                 (c, c - rr, c + rr, c + rr))
    return cv.image


def blob_params(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Harmonic amplitudes (k = 2..6) and phases of the seeded irregular shape."""
    rng = np.random.default_rng([int(seed), 0])
    ks = np.arange(2, 7)
    amps = rng.uniform(0.5, 1.0, len(ks)) * 0.16 / ks ** 0.6
    phases = rng.uniform(0, 2 * np.pi, len(ks))
    return amps, phases


def shape_coverage(size: int, seed: int = 0, ss: int = 4) -> np.ndarray:
    """Coverage (size, size) of the intensity video's irregular shape."""
    amps, phases = blob_params(seed)
    c = size / 2.0
    cv = R.Canvas(np.zeros((size, size), np.float32), ss)
    return cv.paint(R.star_blob(c, c, BLOB_RADIUS * size, amps, phases), 1.0)
