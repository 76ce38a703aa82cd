"""The `Clip` record that `read_video` returns, and the error every video problem raises."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fitode.errors import FitodeError


class VideoError(FitodeError):
    """A video that cannot be read, or video flags that do not fit it (one-line message)."""


@dataclass
class Clip:
    """Preprocessed frames and everything needed to say what they are.

    Sizes are (H, W) tuples, numpy's order; what is printed for people says WxH.
    """

    frames: np.ndarray            # float32 (T, C, H, W) in [0, 1]
    fps: float                    # real-time frame rate of the source (after the fps override)
    fps_source: str               # "container" (read from the file), "timestamps" (the frames' own) or "user" (--fps)
    stride: int                   # every stride-th source frame is kept
    dt: float                     # stride / fps, seconds between kept frames
    stride_reason: str            # why this stride, one sentence
    path: str                     # the input as given
    sha256: str                   # of the file; for a folder see `read_video`
    source_size: tuple[int, int]  # (H, W) of the source frames
    n_source_frames: int          # frames in the source (see `read_video` for --end)
    start_frame: int              # source index of frames[0]
    end_frame: int = 0            # source index one past the trimmed range
    kind: str = "video"           # "video" | "images" | "npy"
    fps_container: float | None = None  # what the container said, even when overridden
    roi: tuple[int, int, int, int] | None = None  # (x, y, w, h) crop in source pixels
    color: bool = False
    mask: str | None = None
    notes: list[str] = field(default_factory=list)  # anything unusual met while reading
    frame_times: np.ndarray | None = None  # real time of every kept frame (s), from the container's stamps
    timing: list[str] = field(default_factory=list)  # what the stamps changed (fitode.video.timing), one line each
    capture_fps: float | None = None  # the capture rate a slow-motion clip's metadata records
    source_index: np.ndarray | None = None  # source frame of every kept frame, where repeats were dropped or holes filled
    # where the moving object is in every kept frame, measured before the frames were shrunk
    # (fitode.video.track; a fitode.train.observe.track.Track), or None
    track: Any = None
    # a few source frames at full resolution, RGB uint8, by source frame index, kept as the read
    # decoded them for the pictures (fitode.video.stills.StillKeeper), or None
    stills: dict | None = field(default=None, repr=False)

    @property
    def frame_indices(self) -> np.ndarray:
        """Source frame index of every kept frame (a frame filled in where the source dropped one:
        the source frame nearest its time)."""
        if self.source_index is not None:
            return np.asarray(self.source_index, np.int64)
        return self.start_frame + self.stride * np.arange(len(self.frames))

    @property
    def times(self) -> np.ndarray:
        """Time of every kept frame in seconds from the start of the source (not of the trim)."""
        if self.frame_times is not None and self.timing:
            return np.asarray(self.frame_times, np.float64)
        return (self.start_frame + self.stride * np.arange(len(self.frames))) / self.fps

    def slow_motion_fps(self) -> float | None:
        """The --fps a slow-motion clip needs, where its metadata records a capture rate above
        the rate in use (None otherwise)."""
        if self.fps_source == "user" or not self.capture_fps or self.capture_fps < 1.5 * self.fps:
            return None
        return self.capture_fps

    @property
    def size(self) -> tuple[int, int]:
        """(H, W) of the preprocessed frames."""
        return int(self.frames.shape[2]), int(self.frames.shape[3])

    def describe(self) -> list[str]:
        """Lines for the command line: input, fps and where from, frames used, size, stride, dt."""
        hs, ws = self.source_size
        t = len(self.frames)
        lines = [f"input: {self.path} ({_KIND_WORDS.get(self.kind, self.kind)}, {ws}x{hs} pixels "
                 f"(WxH), {self.n_source_frames} frames, sha256 {self.sha256[:12]})"]
        if self.fps_source == "user":
            said = (f"; the container says {self.fps_container:.6g}" if self.fps_container
                    else "")
            lines.append(f"fps: {self.fps:.6g} (given by --fps{said})")
        elif self.fps_source == "timestamps":
            said = f"; the container says {self.fps_container:.6g}" if self.fps_container else ""
            lines.append(f"fps: {self.fps:.6g} (from the frames' timestamps{said})")
        else:
            lines.append(f"fps: {self.fps:.6g} (from the container)")
        lines += [f"time: {line}" for line in self.timing]
        if self.track is not None:
            lines.append(f"track: {self.track.note}")
        slow = self.slow_motion_fps()
        if slow:
            lines.append(f"hint: the metadata says this clip was recorded at {slow:.6g} fps and plays at "
                         f"{self.fps:.6g} (slow motion): pass --fps {slow:.6g} for real time; at "
                         f"{self.fps:.6g} fps an acceleration comes out {(slow / self.fps) ** 2:.3g}x too small")
        last = self.start_frame + self.stride * (t - 1) if t else self.start_frame
        every = "every frame" if self.stride == 1 else f"every {_ordinal(self.stride)}"
        if self.frame_times is not None and self.timing and t:
            lines.append(f"frames used: {t} ({every}; {self.times[0]:.3f} s to {self.times[-1]:.3f} s)")
        else:
            lines.append(f"frames used: {t} (source frames {self.start_frame} to {last}, {every}; "
                         f"{self.start_frame / self.fps:.3f} s to {last / self.fps:.3f} s)")
        h, w = self.size
        crop = (f", cropped to x={self.roi[0]} y={self.roi[1]} w={self.roi[2]} h={self.roi[3]}"
                if self.roi else "")
        masked = f", masked by {self.mask}" if self.mask else ""
        lines.append(f"frame size: {w}x{h} pixels (WxH), {'RGB' if self.color else 'gray'}"
                     f"{crop}{masked}")
        lines.append(f"stride: {self.stride} ({self.stride_reason})")
        lines.append(f"dt: {self.dt:.6g} s")
        lines += [f"note: {n}" for n in self.notes]
        return lines


_KIND_WORDS = {"video": "video", "images": "folder of images", "npy": "numpy array"}


def _ordinal(k: int) -> str:
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"
