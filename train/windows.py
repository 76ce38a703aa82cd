"""Overlapping windows over one frame sequence, and the per-frame gather that makes training cheap.

A window of L frames starting at s covers frames s..s+L-1. The official code encodes every frame
once per window that contains it (about L times the work); here each distinct frame in a batch is
encoded once and the windows are gathered from that encoded sequence by index.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class Windows:
    n_frames: int
    length: int

    def __post_init__(self) -> None:
        if self.length < 2:
            raise ValueError("a window needs at least 2 frames")

    @property
    def count(self) -> int:
        return max(self.n_frames - self.length + 1, 0)

    def starts(self) -> torch.Tensor:
        return torch.arange(self.count)

    def index(self, starts: torch.Tensor) -> torch.Tensor:
        """(B,) window starts -> (B, L) frame indices."""
        return starts[:, None] + torch.arange(self.length, device=starts.device)[None, :]


def distinct_frames(index: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Frames a batch of windows needs, each once, and where each window frame sits among them.

    Returns (frames, inverse) with index == frames[inverse]: encode frames, then gather
    encoded[inverse] to get the (B, L, d) windowed latents.
    """
    frames, inverse = torch.unique(index, sorted=True, return_inverse=True)
    return frames, inverse
