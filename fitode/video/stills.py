"""A few source frames at full resolution, for pictures (track.png): the frames a fit used are
shrunk, the drawing of what was measured is not. The read keeps them as it decodes (StillKeeper);
source_stills decodes them again where none were kept (a stretch between two kept frames)."""
from __future__ import annotations

from pathlib import Path
from typing import Iterable, Mapping

import cv2
import numpy as np

from fitode.video.sources import ArraySource, open_source


KEPT = 16  # source frames the read keeps for pictures, spread over the clip (memory flat in its length)
MAX_SIDE = 1280  # a picture needs no more: frames are drawn with imshow's extent in source pixels


class StillKeeper:
    """Keeps up to about KEPT of the frames one streaming pass decodes, spread evenly over them, as
    RGB uint8 at most MAX_SIDE on their long side, so that the pictures (track.png) need no
    second decode of the clip. expected: about how many frames will come (None: unknown; the
    spacing doubles whenever twice KEPT are held)."""

    def __init__(self, order: str, expected: int | None, keep: int = KEPT):
        self.order, self.keep = order, keep
        self.every = max(1, -(-int(expected) // keep)) if expected else 1
        self.count = 0
        self.frames: dict[int, np.ndarray] = {}

    def add(self, index: int, frame: np.ndarray, unit: tuple[float, float]) -> None:
        """One decoded frame, source frame `index`, with its (scale, offset) to [0, 1]."""
        n, self.count = self.count, self.count + 1
        if n % self.every:
            return
        self.frames[int(index)] = np.clip(_rgb(frame, unit, self.order) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        if len(self.frames) > 2 * self.keep:  # more frames came than expected: keep every other
            self.every *= 2
            first = min(self.frames)
            self.frames = {i: f for j, (i, f) in enumerate(sorted(self.frames.items())) if j % 2 == 0 or i == first}


def kept_stills(kept: Mapping[int, np.ndarray] | None, indices: Iterable[int]) -> dict[int, np.ndarray]:
    """{source frame index: RGB float (H, W, 3) in [0, 1]} of the kept frames among indices."""
    return {int(i): kept[int(i)].astype(np.float32) / np.float32(255.0) for i in indices if kept and int(i) in kept}


def source_stills(path: str | Path, indices: Iterable[int], max_side: int = MAX_SIDE) -> dict[int, np.ndarray]:
    """{source frame index: RGB float (H, W, 3) in [0, 1]} for the indices the source holds,
    decoded in one pass that stops after the last; frames larger than max_side on their long side
    are shrunk to it (a picture needs no more: draw them with imshow's extent in source pixels)."""
    wanted = sorted({int(i) for i in indices if int(i) >= 0})
    out: dict[int, np.ndarray] = {}
    if not wanted:
        return out
    src = open_source(Path(path))
    try:
        if isinstance(src, ArraySource):  # an array's value scale is read from its frames (the whole of it here)
            src.calibrate(0, src.arr.shape[0])
        i = 0
        while i <= wanted[-1] and src.grab():
            if i in wanted:
                frame = src.retrieve()
                out[i] = np.clip(_rgb(frame, src.unit(frame), src.order, max_side), 0.0, 1.0)
            i += 1
    finally:
        src.close()
    return out


def _rgb(frame: np.ndarray, unit: tuple[float, float], order: str, max_side: int = MAX_SIDE) -> np.ndarray:
    """A decoded frame as RGB float32 (H, W, 3) in its unit's [0, 1], shrunk to max_side."""
    scale, offset = unit
    if frame.ndim == 3:
        frame = frame[..., :3]
    f = (frame.astype(np.float32) - np.float32(offset)) * np.float32(scale)
    if f.ndim == 2:
        f = np.repeat(f[..., None], 3, axis=2)
    elif order == "BGR":
        f = f[..., ::-1]
    k = min(1.0, max_side / max(f.shape[:2]))
    if k < 1:
        f = cv2.resize(np.ascontiguousarray(f), (round(f.shape[1] * k), round(f.shape[0] * k)),
                       interpolation=cv2.INTER_AREA)
    return f
