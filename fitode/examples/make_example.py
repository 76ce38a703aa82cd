"""Regenerate the bundled example video (and the small test videos the command's tests use).

    python -m fitode.examples.make_example            # writes fitode/examples/pendulum.mp4
    python fitode/examples/make_example.py --out DIR  # somewhere else

The example is a pendulum, theta'' = -g/L*sin(theta) - zeta*theta', with L = 0.25 m and
zeta = 0.15 1/s, released from 12 degrees, filmed for 10 s at 30 fps, 48x48 gray pixels: a
rod from a pivot at the top and a dark bob, anti-aliased by 4x supersampling, with a little
seeded camera noise. Only numpy and OpenCV are needed, so the script shows exactly how the
video was made. pendulum.toml beside it is the equation file the README's command uses.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

G = 9.80665
TRUTH = {"L": 0.25, "zeta": 0.15}
THETA0_DEG = 12.0
FPS = 30.0
DURATION_S = 10.0
SIZE = 48
HERE = Path(__file__).resolve().parent


def pendulum_angles(n_frames: int, fps: float, L: float, zeta: float, theta0: float, omega0: float = 0.0,
                    g: float = G, substeps: int = 50) -> np.ndarray:
    """theta at t = i/fps for the damped pendulum, by RK4 with `substeps` steps per frame."""
    def f(y):
        return np.array([y[1], -g / L * math.sin(y[0]) - zeta * y[1]])
    y = np.array([theta0, omega0], dtype=float)
    h = 1.0 / fps / substeps
    out = np.empty(n_frames)
    for i in range(n_frames):
        out[i] = y[0]
        for _ in range(substeps):
            k1 = f(y)
            k2 = f(y + h / 2 * k1)
            k3 = f(y + h / 2 * k2)
            k4 = f(y + h * k3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return out


def decay_values(n_frames: int, fps: float, gamma: float, i0: float = 1.0) -> np.ndarray:
    """I(t) = i0*exp(-gamma*t) at t = i/fps: the exact solution of I' = -gamma*I."""
    return i0 * np.exp(-gamma * np.arange(n_frames) / fps)


def render_pendulum(angles: np.ndarray, size: int = SIZE, ss: int = 4, noise: float = 2.0,
                    seed: int = 0) -> np.ndarray:
    """uint8 gray frames (T, size, size): light background, a rod and a dark bob."""
    n = size * ss
    yy, xx = (np.mgrid[:n, :n] + 0.5) / ss  # pixel centres of the supersampled grid, in output pixels
    px, py = size / 2.0, 0.06 * size  # pivot near the top
    arm, bob, rod = 0.72 * size, 0.11 * size, 0.035 * size
    rng = np.random.default_rng(seed)
    frames = np.empty((len(angles), size, size), dtype=np.uint8)
    for i, th in enumerate(angles):
        bx, by = px + arm * math.sin(th), py + arm * math.cos(th)
        # distance to the rod segment pivot -> bob
        vx, vy = bx - px, by - py
        tpar = np.clip(((xx - px) * vx + (yy - py) * vy) / (vx * vx + vy * vy), 0.0, 1.0)
        d_rod = np.hypot(xx - (px + tpar * vx), yy - (py + tpar * vy))
        d_bob = np.hypot(xx - bx, yy - by)
        img = np.full((n, n), 205.0)
        img[d_rod <= rod] = 90.0
        img[d_bob <= bob] = 35.0
        small = img.reshape(size, ss, size, ss).mean(axis=(1, 3))
        small += rng.normal(0.0, noise, small.shape)
        frames[i] = np.clip(np.round(small), 0, 255).astype(np.uint8)
    return frames


def render_glow(values: np.ndarray, size: int = 32, background: float = 20.0, peak: float = 220.0,
                noise: float = 1.0, seed: int = 0) -> np.ndarray:
    """uint8 gray frames (T, size, size) of a soft glowing spot whose brightness is `values` (0..1)."""
    yy, xx = np.mgrid[:size, :size]
    spot = np.exp(-((xx - size / 2 + 0.5) ** 2 + (yy - size / 2 + 0.5) ** 2) / (2 * (size / 5) ** 2))
    rng = np.random.default_rng(seed)
    out = background + peak * np.asarray(values)[:, None, None] * spot[None] + rng.normal(0, noise, (len(values), size, size))
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def write_mp4(path: str | Path, frames: np.ndarray, fps: float) -> Path:
    """Gray uint8 frames (T, H, W) -> an mp4 (MPEG-4 part 2, which every OpenCV build writes)."""
    import cv2
    path = Path(path)
    h, w = frames.shape[1:3]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (int(w), int(h)), True)
    if not writer.isOpened():
        raise RuntimeError(f"OpenCV cannot write {path}")
    try:
        for f in frames:
            writer.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
    finally:
        writer.release()
    return path


def make_example(out_dir: str | Path = HERE) -> Path:
    n = int(round(DURATION_S * FPS))
    angles = pendulum_angles(n, FPS, TRUTH["L"], TRUTH["zeta"], math.radians(THETA0_DEG))
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    return write_mp4(Path(out_dir) / "pendulum.mp4", render_pendulum(angles), FPS)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(HERE), help="folder to write pendulum.mp4 into")
    args = p.parse_args(argv)
    path = make_example(args.out)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB); truth L = {TRUTH['L']} m, "
          f"zeta = {TRUTH['zeta']} 1/s, g = {G}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
