"""The plain data every generator returns."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class SynthVideo:
    """A rendered video and the truth behind it.

    frames: (T, H, W) gray or (T, H, W, 3) RGB. The clean renders (paper datasets, rendered
        equations) are float32 in [0, 1], exactly as drawn; the realistic scenes are uint8
        (0..255), as a camera that compresses its frames delivers them. `as_float()` and
        `as_tensor_frames()` give float32 in [0, 1] either way.
    dt: seconds between frames (fps = 1/dt).
    truth: the true constants, by the names of `equation`.
    latent: (T, dim) the true state variables at each frame (one column per state, named
        by latent_names), in the units of `equation`.
    equation: the equation the latent obeys, as fitode reads it.
    state: (T, n) the full first-order state (values and derivatives, named by
        state_names) where the generator knows it, else None.
    meta: generator settings (kind, seed, how the latent is drawn, ...), JSON-serialisable.
    pixels: (T, 2) the moving object's true centre (x right, y down) in pixels, pixel (0, 0)'s
        centre at (0, 0), where the scene knows it (the spring's can), else None.
    """

    frames: np.ndarray
    dt: float
    truth: dict[str, float]
    latent: np.ndarray
    equation: str
    latent_names: tuple[str, ...] = ("z",)
    state: np.ndarray | None = None
    state_names: tuple[str, ...] = ()
    meta: dict = field(default_factory=dict)
    pixels: np.ndarray | None = None

    @property
    def fps(self) -> float:
        return 1.0 / self.dt

    @property
    def n_frames(self) -> int:
        return int(self.frames.shape[0])

    @property
    def size(self) -> tuple[int, int]:
        """(height, width) in pixels."""
        return int(self.frames.shape[1]), int(self.frames.shape[2])

    @property
    def channels(self) -> int:
        return 1 if self.frames.ndim == 3 else int(self.frames.shape[3])

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.n_frames) * self.dt

    def as_float(self) -> np.ndarray:
        """Frames as float32 in [0, 1], same layout as `frames`."""
        if self.frames.dtype == np.uint8:
            return self.frames.astype(np.float32) / 255.0
        return self.frames.astype(np.float32, copy=False)

    def as_tensor_frames(self):
        """float32 torch tensor (T, C, H, W) in [0, 1]: what the trainer eats."""
        import torch

        x = self.as_float()
        x = x[:, None] if x.ndim == 3 else np.transpose(x, (0, 3, 1, 2))
        return torch.from_numpy(np.ascontiguousarray(x))

    def __repr__(self) -> str:
        kind = self.meta.get("generator", "synth")
        name = self.meta.get("kind") or self.meta.get("name") or ""
        return (f"SynthVideo({kind} {name}: {self.n_frames} frames {self.size[1]}x{self.size[0]}"
                f"x{self.channels} {self.frames.dtype}, dt={self.dt:g}, truth={self.truth})")
