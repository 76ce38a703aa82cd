"""The --mask: an image or array applied to every frame, or a video, folder or (T, H, W) array
whose frame i is applied to source frame i."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from fitode.video.clip import VideoError
from fitode.video.sources import (IMAGE_SUFFIXES, ImageSource, Source, VideoSource, dtype_unit,
                                  first_line)


class Mask:
    """A mask image (one array for every frame) or a mask video (frame i for source frame i),
    prepared at source resolution and cropped to `roi`, the box the frames are cut to."""

    def __init__(self, path: Path, source_hw: tuple[int, int], roi: tuple[int, int, int, int]):
        self.path = path
        self.hw = source_hw
        self.roi = roi
        self.note: str | None = None
        self.static: np.ndarray | None = None
        self.frames: Source | None = None
        self.n = 0
        if not path.exists():
            raise VideoError(f"--mask {path}: no such file")
        suffix = path.suffix.lower()
        if suffix == ".npy":
            try:
                arr = np.load(path, allow_pickle=False)
            except (ValueError, OSError, EOFError) as exc:
                raise VideoError(f"--mask {path}: not a readable .npy array ({first_line(exc)})") from None
            if arr.ndim not in (2, 3) or not (arr.dtype == np.bool_ or np.issubdtype(arr.dtype, np.number)):
                raise VideoError(f"--mask {path}: a .npy mask must be numbers shaped (H, W) or "
                                 f"(T, H, W); got {arr.dtype} {tuple(arr.shape)}")
            arr = arr.astype(np.float32) * np.float32(_mask_scale(arr))
            if arr.ndim == 2:
                self.static = self._prepare(arr, (1.0, 0.0))
            else:
                self.frames = _MaskArray(arr)
            return
        if path.is_file() and suffix in IMAGE_SUFFIXES:
            img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)
            if img is None:
                raise VideoError(f"--mask {path}: cannot read this image")
            self.static = self._prepare(img, (_mask_scale(img), 0.0))
            return
        try:
            self.frames = VideoSource(path) if path.is_file() else ImageSource(path)
        except VideoError as exc:
            raise VideoError(f"--mask {exc}") from None

    def _prepare(self, img: np.ndarray, unit: tuple[float, float]) -> np.ndarray:
        if img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[-1] == 3 else cv2.COLOR_BGRA2GRAY)
        m = (img.astype(np.float32) - unit[1]) * unit[0]
        h, w = self.hw
        if m.shape != (h, w):
            if self.note is None:
                self.note = f"mask resized from {m.shape[1]}x{m.shape[0]} to the frame's {w}x{h} (WxH)"
            shrink = m.shape[0] > h or m.shape[1] > w
            m = cv2.resize(m, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        np.clip(m, 0.0, 1.0, out=m)
        x, y, cw, ch = self.roi
        return np.ascontiguousarray(m[y:y + ch, x:x + cw])

    def grab(self) -> None:
        """Advance with the source (mask videos only)."""
        if self.frames is not None:
            if not self.frames.grab():
                raise VideoError(f"--mask {self.path}: the mask video has only {self.n} frames, "
                                 f"fewer than the video it masks")
            self.n += 1

    def current(self) -> np.ndarray:
        if self.static is not None:
            return self.static
        assert self.frames is not None
        f = self.frames.retrieve()
        return self._prepare(f, self.frames.unit(f))

    def close(self) -> None:
        if self.frames is not None:
            self.frames.close()


def _mask_scale(arr: np.ndarray) -> float:
    """Factor taking a mask array to [0, 1]. Values already within [0, 1] (a 0/1 label mask,
    even stored as 8-bit) are kept; otherwise 8/16-bit values are divided by their type's
    maximum and anything else by its own maximum."""
    top = float(arr.max()) if arr.size else 0.0
    if top <= 1.0:
        return 1.0
    if arr.dtype in (np.uint8, np.uint16):
        return dtype_unit(arr.dtype)[0]
    return 1.0 / top


class _MaskArray(Source):
    """Frames of a (T, H, W) mask array, already float."""

    def __init__(self, arr: np.ndarray):
        self.arr = arr
        self.i = -1

    def grab(self) -> bool:
        self.i += 1
        return self.i < self.arr.shape[0]

    def retrieve(self) -> np.ndarray:
        return self.arr[self.i]
