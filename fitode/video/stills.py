"""A few source frames at full resolution, for pictures (track.png): the frames a fit used are
shrunk, the drawing of what was measured is not."""
from __future__ import annotations

from pathlib import Path
from typing import Iterable

import cv2
import numpy as np

from fitode.video.sources import open_source


def source_stills(path: str | Path, indices: Iterable[int], max_side: int = 1280) -> dict[int, np.ndarray]:
    """{source frame index: RGB float (H, W, 3) in [0, 1]} for the indices the source holds,
    decoded in one pass that stops after the last; frames larger than max_side on their long side
    are shrunk to it (a picture needs no more: draw them with imshow's extent in source pixels)."""
    wanted = sorted({int(i) for i in indices if int(i) >= 0})
    out: dict[int, np.ndarray] = {}
    if not wanted:
        return out
    src = open_source(Path(path))
    try:
        i = 0
        while i <= wanted[-1] and src.grab():
            if i in wanted:
                frame = src.retrieve()
                scale, offset = src.unit(frame)
                if frame.ndim == 3:
                    frame = frame[..., :3]
                f = (frame.astype(np.float32) - np.float32(offset)) * np.float32(scale)
                if f.ndim == 2:
                    f = np.repeat(f[..., None], 3, axis=2)
                elif src.order == "BGR":
                    f = f[..., ::-1]
                k = min(1.0, max_side / max(f.shape[:2]))
                if k < 1:
                    f = cv2.resize(np.ascontiguousarray(f), (round(f.shape[1] * k), round(f.shape[0] * k)),
                                   interpolation=cv2.INTER_AREA)
                out[i] = np.clip(f, 0.0, 1.0)
            i += 1
    finally:
        src.close()
    return out

