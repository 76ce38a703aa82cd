"""Reading a video (or a folder of images, or a .npy array) into small preprocessed frames.

    clip = read_video("pendulum.mp4", fps=120, start=2.0, roi=(100, 0, 400, 300))
    clip.frames      # float32 (T, C, H, W) in [0, 1]
    clip.dt          # seconds between kept frames: stride / fps

Order of operations, per frame, while decoding: trim (start/end) -> crop (roi) -> gray (or RGB)
-> multiply by the mask -> resize -> keep every stride-th frame. Only one full-resolution frame
is alive at a time; what accumulates is the small preprocessed frames (about 29 KB each at the
default 64-pixel short side, gray). With `stride="auto"` every frame of the trimmed range is
kept until the stride is chosen (see `fitode.stride`), then only every stride-th.

Times (`start`, `end`, `Clip.times`) are in the seconds of the frame rate in use: with
`fps=120` on a slow-motion clip that the container calls 30 fps, they are real seconds, not
playback seconds.
"""
from __future__ import annotations

import hashlib
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

# FFmpeg prints errors such as "moov atom not found" straight to stderr when OpenCV probes a bad
# file; our own one-line VideoError says it better. Read once, when OpenCV first opens FFmpeg.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from fitode.errors import FitodeError  # noqa: E402
from fitode.stride import auto_stride  # noqa: E402

__all__ = ["Clip", "VideoError", "read_video", "parse_roi", "parse_size", "parse_stride",
           "add_video_arguments", "video_kwargs", "IMAGE_SUFFIXES", "MAX_FPS"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm",
                  ".pbm", ".pnm", ".jp2", ".exr", ".hdr")
MAX_FPS = 10000.0
# Container "frame rates" that are really time bases (Matroska/WebM 1/1000, MPEG-TS 1/90000):
# FFmpeg reports them for variable-rate files whose true rate it cannot tell.
_TIME_BASES = (1000.0, 90000.0)


class VideoError(FitodeError):
    """A video that cannot be read, or video flags that do not fit it (one-line message)."""


@dataclass
class Clip:
    """Preprocessed frames and everything needed to say what they are."""

    frames: np.ndarray            # float32 (T, C, H, W) in [0, 1]
    fps: float                    # real-time frame rate of the source (after the fps override)
    fps_source: str               # "container" (read from the file) or "user" (the fps argument)
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

    @property
    def frame_indices(self) -> np.ndarray:
        """Source frame index of every kept frame."""
        return self.start_frame + self.stride * np.arange(len(self.frames))

    @property
    def times(self) -> np.ndarray:
        """Time of every kept frame in seconds from the start of the source (not of the trim)."""
        return self.frame_indices / self.fps

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
        else:
            lines.append(f"fps: {self.fps:.6g} (from the container)")
        last = self.start_frame + self.stride * (t - 1) if t else self.start_frame
        every = "every frame" if self.stride == 1 else f"every {_ordinal(self.stride)}"
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


# ----------------------------------------------------------------------------- flag parsers

def parse_roi(text: str) -> tuple[int, int, int, int]:
    """'x,y,w,h' (pixels of the source frame, x to the right, y down) -> (x, y, w, h)."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) != 4:
            raise ValueError
        x, y, w, h = (int(p) for p in parts)
    except ValueError:
        raise VideoError(f"--roi expects x,y,w,h: four whole numbers of pixels such as "
                         f"10,20,300,200; got {text!r}") from None
    if x < 0 or y < 0 or w < 1 or h < 1:
        raise VideoError(f"--roi {text}: x and y must be >= 0 and w and h >= 1")
    return x, y, w, h


def parse_size(text: str) -> tuple[int, int]:
    """'HxW' (height first, like numpy) -> (H, W)."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX*]\s*(\d+)\s*", str(text))
    if not m:
        raise VideoError(f"--size expects HxW in pixels (height first), such as 64x64; got {text!r}")
    h, w = int(m.group(1)), int(m.group(2))
    if h < 1 or w < 1:
        raise VideoError(f"--size {text}: both sides must be at least 1 pixel")
    return h, w


def parse_stride(text: str | int) -> int | str:
    """'auto' or a whole number >= 1."""
    s = str(text).strip()
    if s.lower() == "auto":
        return "auto"
    try:
        k = int(s)
    except ValueError:
        raise VideoError(f"--stride expects 'auto' or a whole number of frames >= 1; got {text!r}") from None
    if k < 1:
        raise VideoError(f"--stride must be at least 1; got {text!r}")
    return k


def add_video_arguments(parser) -> None:
    """Add the video flags (--fps --start --end --roi --size --color --stride --mask) to an
    argparse parser; `video_kwargs(args)` turns the parsed values into read_video's keywords."""
    g = parser.add_argument_group("video")
    g.add_argument("--fps", type=float, default=None,
                   help="real frame rate; wins over the file's (needed for slow motion, folders "
                        "of images and .npy)")
    g.add_argument("--start", type=float, default=None, help="first time used, in seconds")
    g.add_argument("--end", type=float, default=None, help="time (seconds) where use stops")
    g.add_argument("--roi", type=parse_roi, default=None, metavar="X,Y,W,H",
                   help="crop, in pixels of the source frame")
    g.add_argument("--size", type=parse_size, default=None, metavar="HxW",
                   help="frame size after resizing (default: short side 64, aspect kept)")
    g.add_argument("--color", action="store_true", help="keep RGB channels (default gray)")
    g.add_argument("--stride", type=parse_stride, default="auto", metavar="K|auto",
                   help="use every K-th frame, dt = K/fps (default: auto)")
    g.add_argument("--mask", default=None, metavar="PATH",
                   help="image or video multiplied with the frames (0 hides, 1 keeps)")


def video_kwargs(args) -> dict:
    """read_video keywords from the flags that `add_video_arguments` added."""
    return {k: getattr(args, k) for k in
            ("fps", "start", "end", "roi", "size", "color", "stride", "mask")}


# ----------------------------------------------------------------------------- sources

class _Source:
    """Sequential frames. `grab` advances (cheaply), `retrieve` returns the current frame."""

    kind = "video"
    container_fps: float | None = None
    count_hint: int | None = None
    order = "BGR"  # channel order of 3-channel frames

    def grab(self) -> bool:
        raise NotImplementedError

    def retrieve(self) -> np.ndarray:
        raise NotImplementedError

    def unit(self, frame: np.ndarray) -> tuple[float, float]:
        """(scale, offset) so that (frame - offset) * scale lies in [0, 1]."""
        return _dtype_unit(frame.dtype)

    def close(self) -> None:
        pass


def _dtype_unit(dtype: np.dtype) -> tuple[float, float]:
    if dtype == np.uint8:
        return 1.0 / 255.0, 0.0
    if dtype == np.uint16:
        return 1.0 / 65535.0, 0.0
    return 1.0, 0.0


class _VideoSource(_Source):
    def __init__(self, path: Path):
        self.name = path.name
        old = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        try:
            self.cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        finally:
            cv2.utils.logging.setLogLevel(old)
        if not self.cap.isOpened():
            raise VideoError(f"{path}: cannot read it as a video (OpenCV's FFmpeg could not open it)")
        fps = self.cap.get(cv2.CAP_PROP_FPS)
        self.container_fps = float(fps) if math.isfinite(fps) else None
        count = self.cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.count_hint = int(count) if math.isfinite(count) and 0 < count < 1e8 else None

    def grab(self) -> bool:
        return bool(self.cap.grab())

    def retrieve(self) -> np.ndarray:
        ok, frame = self.cap.retrieve()
        if not ok or frame is None:
            raise VideoError(f"{self.name}: a frame was found but could not be decoded")
        return frame

    def close(self) -> None:
        self.cap.release()


def _natural_key(name: str) -> list:
    return [(0, int(s), "") if s.isdigit() else (1, 0, s.lower()) for s in re.split(r"(\d+)", name)]


def _image_files(folder: Path) -> list[Path]:
    files = [p for p in folder.iterdir()
             if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in IMAGE_SUFFIXES]
    return sorted(files, key=lambda p: _natural_key(p.name))


class _ImageSource(_Source):
    kind = "images"

    def __init__(self, folder: Path):
        self.files = _image_files(folder)
        if not self.files:
            raise VideoError(f"{folder}: the folder holds no images (looked for "
                             f"{', '.join(IMAGE_SUFFIXES[:5])}, ...)")
        self.count_hint = len(self.files)
        self.i = -1

    def grab(self) -> bool:
        self.i += 1
        return self.i < len(self.files)

    def retrieve(self) -> np.ndarray:
        p = self.files[self.i]
        img = cv2.imread(str(p), cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)
        if img is None:
            raise VideoError(f"{p}: cannot read this image")
        return img


class _ArraySource(_Source):
    kind = "npy"
    order = "RGB"

    def __init__(self, path: Path):
        try:
            arr = np.load(path, mmap_mode="r", allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise VideoError(f"{path}: not a readable .npy array ({_first_line(exc)})") from None
        if not isinstance(arr, np.ndarray):
            raise VideoError(f"{path}: expected one array in a .npy file")
        if arr.ndim == 4 and arr.shape[-1] in (1, 3, 4):
            pass
        elif arr.ndim != 3:
            raise VideoError(f"{path}: expected frames shaped (T, H, W) or (T, H, W, C) with C 1, 3 "
                             f"or 4; got shape {tuple(arr.shape)}")
        if not (arr.dtype == np.bool_ or np.issubdtype(arr.dtype, np.integer)
                or np.issubdtype(arr.dtype, np.floating)):
            raise VideoError(f"{path}: frames must be numbers; got dtype {arr.dtype}")
        self.arr = arr
        self.name = path.name
        self.count_hint = int(arr.shape[0])
        self.i = -1
        self.scale_offset: tuple[float, float] | None = None
        self.note: str | None = None

    def calibrate(self, lo: int, hi: int) -> None:
        """Fix the value scale from the frames [lo, hi) that will be used (floats and wide ints)."""
        a = self.arr
        if a.dtype in (np.uint8, np.uint16, np.bool_):
            self.scale_offset = (1.0, 0.0) if a.dtype == np.bool_ else _dtype_unit(a.dtype)
            return
        vmin, vmax = math.inf, -math.inf
        step = max(1, (32 * 2**20) // max(1, a[0].nbytes))
        for j in range(lo, hi, step):
            block = np.asarray(a[j:min(hi, j + step)], dtype=np.float64)
            if not np.isfinite(block).all():
                raise VideoError(f"{self.name}: the array holds NaN or infinite values")
            vmin, vmax = min(vmin, float(block.min())), max(vmax, float(block.max()))
        if vmin >= 0.0 and vmax <= 1.0:
            self.scale_offset = (1.0, 0.0)
        elif vmax > vmin:
            self.scale_offset = (1.0 / (vmax - vmin), vmin)
            self.note = f"values rescaled from [{vmin:.4g}, {vmax:.4g}] to [0, 1]"
        else:
            self.scale_offset = (1.0, 0.0)  # constant outside [0, 1]: clipped below
            self.note = f"every value is {vmin:.4g}, outside [0, 1]: clipped"

    def grab(self) -> bool:
        self.i += 1
        return self.i < self.arr.shape[0]

    def retrieve(self) -> np.ndarray:
        f = np.asarray(self.arr[self.i])
        if f.ndim == 3 and f.shape[-1] == 1:
            f = f[..., 0]
        elif f.ndim == 3 and f.shape[-1] == 4:
            f = f[..., :3]
        if f.dtype == np.bool_:
            f = f.astype(np.uint8)
        elif f.dtype not in (np.uint8, np.uint16, np.float32):
            f = f.astype(np.float32)  # cvtColor takes 8U, 16U and 32F only
        return f

    def unit(self, frame: np.ndarray) -> tuple[float, float]:
        assert self.scale_offset is not None
        return self.scale_offset


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


# ----------------------------------------------------------------------------- mask

class _Mask:
    """A mask image (one array for every frame) or a mask video (frame i for source frame i)."""

    def __init__(self, path: Path, source_hw: tuple[int, int], roi: tuple[int, int, int, int]):
        self.path = path
        self.hw = source_hw
        self.roi = roi
        self.note: str | None = None
        self.static: np.ndarray | None = None
        self.frames: _Source | None = None
        self.n = 0
        if not path.exists():
            raise VideoError(f"--mask {path}: no such file")
        suffix = path.suffix.lower()
        if suffix == ".npy":
            try:
                arr = np.load(path, allow_pickle=False)
            except (ValueError, OSError, EOFError) as exc:
                raise VideoError(f"--mask {path}: not a readable .npy array ({_first_line(exc)})") from None
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
            self.frames = _VideoSource(path) if path.is_file() else _ImageSource(path)
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


def _mask_scale(arr: np.ndarray) -> float:
    """Factor taking a mask array to [0, 1]. Values already within [0, 1] (a 0/1 label mask,
    even stored as 8-bit) are kept; otherwise 8/16-bit values are divided by their type's
    maximum and anything else by its own maximum."""
    top = float(arr.max()) if arr.size else 0.0
    if top <= 1.0:
        return 1.0
    if arr.dtype in (np.uint8, np.uint16):
        return _dtype_unit(arr.dtype)[0]
    return 1.0 / top


class _MaskArray(_Source):
    """Frames of a (T, H, W) mask array, already float."""

    def __init__(self, arr: np.ndarray):
        self.arr = arr
        self.i = -1

    def grab(self) -> bool:
        self.i += 1
        return self.i < self.arr.shape[0]

    def retrieve(self) -> np.ndarray:
        return self.arr[self.i]


# ----------------------------------------------------------------------------- reading

def read_video(path: str | Path, *, fps: float | None = None, start: float | None = None,
               end: float | None = None, roi: tuple[int, int, int, int] | None = None,
               size: tuple[int, int] | None = None, color: bool = False,
               stride: int | str = "auto", mask: str | Path | None = None, short_side: int = 64,
               progress: bool = False) -> Clip:
    """Read and preprocess frames; every problem is a one-line `VideoError`.

    path: a video file (anything OpenCV's FFmpeg reads: mp4, avi, mov, mkv, webm, gif, ...), a
        folder of images (used in natural order, img2 before img10; needs `fps`), or a .npy array
        (T, H, W) or (T, H, W, C) of uint8, uint16, bool or float (floats outside [0, 1] are
        rescaled by their min and max; needs `fps`; channels are taken as RGB).
    fps: the real frame rate; always wins over the container's (slow-motion clips report their
        playback rate). A container rate that is missing, <= 0, NaN, above 10000, or exactly
        1000 or 90000 (time bases, not rates) is refused with a request for `fps`.
    start, end: trim, in seconds at that frame rate; frame i (time i/fps) is kept when
        start <= i/fps < end. Both must lie within the video.
    roi: (x, y, w, h) crop in source pixels; must lie inside the frame.
    size: (H, W) output size. Default: scale so the short side is `short_side` (never upscaling,
        and never letting the long side exceed 4 * short_side, for very elongated frames).
    color: keep RGB channels (C = 3); default gray (C = 1).
    stride: keep every stride-th frame (dt = stride / fps), or "auto": see `fitode.stride`.
    mask: an image or .npy (H, W) (any size: it is resized to the source frame), or a mask
        video, folder of images or .npy (T, H, W) whose frame i multiplies source frame i. Gray
        values: 8-bit 0..255 means 0..1, but an image or array whose values all lie in [0, 1]
        (a 0/1 label mask) is used as is. Applied at source resolution, after the crop and
        before the resize.
    progress: show a progress bar on stderr.

    `sha256` is that of the file; for a folder it is the SHA-256 of the text made of one line
    per image, in the order used: the file name, a tab, the SHA-256 of its bytes.
    `n_source_frames` is exact for folders and arrays, and for a video file the number of frames
    decoded when decoding reached its end; when `end` stopped it earlier, the larger of the
    container's count and the frames seen.
    """
    p = Path(path)
    if not p.exists():
        raise VideoError(f"{path}: no such file or folder")
    fps = _check_user_fps(fps)
    stride_arg = parse_stride(stride) if not isinstance(stride, int) or isinstance(stride, bool) \
        else stride
    if isinstance(stride_arg, int) and stride_arg < 1:
        raise VideoError(f"--stride must be at least 1; got {stride}")
    if roi is not None:
        roi = _check_roi(roi)
    if size is not None:
        size = _check_size(size)
    try:
        side = int(short_side)
    except (TypeError, ValueError):
        side = 0
    if side < 1:
        raise VideoError(f"the short side must be a whole number of pixels >= 1; got {short_side!r}")
    start, end = _seconds("--start", start), _seconds("--end", end)
    if start is not None and end is not None and start >= end:
        raise VideoError(f"--start ({start:g} s) must come before --end ({end:g} s)")

    if p.is_dir():
        src: _Source = _ImageSource(p)
    elif p.suffix.lower() == ".npy":
        src = _ArraySource(p)
    else:
        src = _VideoSource(p)
    try:
        return _read(p, src, fps, start, end, roi, size, bool(color), stride_arg,
                     None if mask is None else Path(mask), side, progress)
    finally:
        src.close()


def _seconds(name: str, value) -> float | None:
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v) or v < 0:
        raise VideoError(f"{name} must be a time in seconds >= 0; got {value!r}")
    return v


def _check_user_fps(fps: float | None) -> float | None:
    if fps is None:
        return None
    try:
        v = float(fps)
    except (TypeError, ValueError):
        raise VideoError(f"--fps expects a number of frames per second; got {fps!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise VideoError(f"--fps must be a positive number of frames per second; got {fps}")
    return v


def _container_fps_problem(v: float | None) -> str | None:
    if v is None or not math.isfinite(v) or v <= 0:
        return "no frame rate"
    if v > MAX_FPS:
        return f"{v:.6g} fps, which is not a plausible frame rate"
    if any(abs(v - tb) < 1e-6 * tb for tb in _TIME_BASES):
        return f"{v:.6g} fps, which is a time base rather than a frame rate"
    return None


def _check_roi(roi) -> tuple[int, int, int, int]:
    try:
        x, y, w, h = (int(v) for v in roi)
    except (TypeError, ValueError):
        raise VideoError(f"roi must be (x, y, w, h) in pixels; got {roi!r}") from None
    return parse_roi(f"{x},{y},{w},{h}")


def _check_size(size) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in size)
    except (TypeError, ValueError):
        raise VideoError(f"size must be (H, W) in pixels; got {size!r}") from None
    return parse_size(f"{h}x{w}")


def _default_size(h: int, w: int, short_side: int) -> tuple[int, int]:
    scale = min(1.0, short_side / min(h, w), 4.0 * short_side / max(h, w))
    return max(1, round(h * scale)), max(1, round(w * scale))


def _sha256(p: Path, src: _Source) -> str:
    try:
        if isinstance(src, _ImageSource):
            lines = "".join(f"{f.name}\t{_file_sha256(f)}\n" for f in src.files)
            return hashlib.sha256(lines.encode()).hexdigest()
        return _file_sha256(p)
    except OSError as exc:
        raise VideoError(f"{p}: cannot read it ({_first_line(exc)})") from None


def _file_sha256(p: Path) -> str:
    h = hashlib.sha256()
    with open(p, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _frame_range(fps: float, start: float | None, end: float | None) -> tuple[int, int | None]:
    # Frame i sits at i/fps; keep start <= i/fps < end. The epsilon absorbs decimal input such as
    # --start 1.0 at 29.97 fps landing a hair above an integer.
    first = max(0, math.ceil(float(start) * fps - 1e-6)) if start is not None else 0
    stop = max(0, math.ceil(float(end) * fps - 1e-6)) if end is not None else None
    return first, stop


def _read(p: Path, src: _Source, fps: float | None, start, end, roi, size, color: bool,
          stride_arg: int | str, mask_path: Path | None, short_side: int, progress: bool) -> Clip:
    name = p.name or str(p)
    if fps is not None:
        fps_used, fps_source = fps, "user"
    elif src.kind != "video":
        what = "a folder of images" if src.kind == "images" else "a .npy array"
        raise VideoError(f"{name}: {what} has no frame rate; pass --fps")
    else:
        problem = _container_fps_problem(src.container_fps)
        if problem:
            raise VideoError(f"{name}: the file reports {problem}; pass the real one with --fps")
        fps_used, fps_source = float(src.container_fps), "container"  # type: ignore[arg-type]

    first, stop = _frame_range(fps_used, start, end)
    if stop is not None and first >= stop:
        raise VideoError(f"--start {start:g} s and --end {end:g} s keep no frame at {fps_used:.6g} fps")
    if isinstance(src, _ArraySource):
        total = src.arr.shape[0]
        if total and first < total:
            src.calibrate(first, min(total, stop) if stop is not None else total)
    sha = _sha256(p, src)

    explicit = stride_arg if isinstance(stride_arg, int) else None
    notes: list[str] = []
    buf: np.ndarray | None = None
    kept = 0
    hw: tuple[int, int] | None = None
    pipe: _Pipeline | None = None
    the_mask: _Mask | None = None

    hint = src.count_hint
    todo = hint if stop is None else (stop if hint is None else min(stop, hint))
    bar = _progress(progress, todo, name)
    i = 0
    try:
        while stop is None or i < stop:
            if not src.grab():
                break
            if the_mask is not None:
                the_mask.grab()
            use = i >= first and (explicit is None or (i - first) % explicit == 0)
            if i == 0 or use:
                frame = src.retrieve()
                if hw is None:
                    hw = (int(frame.shape[0]), int(frame.shape[1]))
                    crop = roi or (0, 0, hw[1], hw[0])
                    _roi_inside(crop, hw)
                    out_hw = size or _default_size(crop[3], crop[2], short_side)
                    pipe = _Pipeline(crop, out_hw, color, src.order)
                    if mask_path is not None:
                        the_mask = _Mask(mask_path, hw, pipe.box)
                        the_mask.grab()  # catch up with frame 0
                elif frame.shape[:2] != hw:
                    raise VideoError(f"{name}: frame {i} is {frame.shape[1]}x{frame.shape[0]} "
                                     f"(WxH), unlike the first frame's {hw[1]}x{hw[0]}")
                if use:
                    assert pipe is not None
                    small = pipe(frame, src.unit(frame),
                                 the_mask.current() if the_mask is not None else None)
                    if buf is None or kept == buf.shape[0]:
                        buf = _grow(buf, kept, small.shape, todo, first, explicit)
                    buf[kept] = small
                    kept += 1
            i += 1
            bar.update(1)
    finally:
        bar.close()
        if the_mask is not None and the_mask.frames is not None:
            the_mask.frames.close()

    decoded = i
    at_end = stop is None or decoded < stop
    if decoded == 0:
        raise VideoError(f"{name}: no frame could be decoded")
    duration = decoded / fps_used
    if first >= decoded:
        raise VideoError(f"--start {start:g} s is at or past the end of the video ({duration:.3f} s, "
                         f"{decoded} frames at {fps_used:.6g} fps)")
    if stop is not None and decoded < stop:
        raise VideoError(f"--end {end:g} s is past the end of the video ({duration:.3f} s, "
                         f"{decoded} frames at {fps_used:.6g} fps)")
    assert buf is not None and hw is not None

    # A view, not a copy, when every buffered frame is kept: the buffer's unused tail was never
    # written, so it holds no memory, while a copy would briefly double the frames.
    if explicit is not None:
        k, reason = explicit, "given by --stride"
    else:
        choice = auto_stride(buf[:kept], fps_used)
        k, reason = choice.stride, choice.reason
    frames = buf[:kept] if explicit is not None or k == 1 else buf[:kept:k].copy()
    del buf

    if src.kind != "video" and src.count_hint is not None:
        n_source = src.count_hint  # exact for folders and arrays
    elif at_end:
        n_source = decoded
    else:
        n_source = max(decoded, src.count_hint or 0)
    if src.kind == "video" and at_end and src.count_hint and src.count_hint != decoded:
        notes.append(f"the container claims {src.count_hint} frames but {decoded} could be decoded")
    if isinstance(src, _ArraySource) and src.note:
        notes.append(src.note)
    if the_mask is not None and the_mask.note:
        notes.append(the_mask.note)
    return Clip(frames=frames, fps=fps_used, fps_source=fps_source, stride=k, dt=k / fps_used,
                stride_reason=reason, path=str(p), sha256=sha, source_size=hw,
                n_source_frames=n_source, start_frame=first,
                end_frame=decoded if stop is None else stop, kind=src.kind,
                fps_container=src.container_fps, roi=roi, color=color,
                mask=None if mask_path is None else str(mask_path), notes=notes)


def _roi_inside(roi: tuple[int, int, int, int], hw: tuple[int, int]) -> None:
    x, y, w, h = roi
    H, W = hw
    if x + w > W or y + h > H:
        raise VideoError(f"--roi {x},{y},{w},{h} reaches outside the {W}x{H} (WxH) frame: "
                         f"x+w = {x + w} must be <= {W} and y+h = {y + h} <= {H}")


def _grow(buf: np.ndarray | None, kept: int, shape: tuple[int, ...], hint: int | None,
          first: int, explicit: int | None) -> np.ndarray:
    """A larger frame buffer. The first guess comes from the container's count (np.empty
    commits no memory for frames never written); later growth is by half."""
    if buf is None:
        guess = max(1, (hint or 256) - first)
        if explicit:
            guess = -(-guess // explicit)
        new = np.empty((guess + 1,) + shape, np.float32)
    else:
        new = np.empty((max(kept + 16, kept * 3 // 2),) + shape, np.float32)
        new[:kept] = buf[:kept]
    return new


class _Pipeline:
    """crop -> gray/RGB -> float in [0, 1] -> mask -> resize -> (C, H, W), for one frame."""

    def __init__(self, roi: tuple[int, int, int, int], out_hw: tuple[int, int], color: bool,
                 order: str):
        self.color = color
        self.order = order
        self.out_hw = out_hw
        x, y, w, h = roi
        # OpenCV's INTER_AREA is ~6x faster for a whole-number factor than for an arbitrary one
        # (1.2 ms against 7 ms on a 1080p frame). So shrink by the largest whole factor that keeps
        # the frame at least the output size, then area-resample the small remainder. For that
        # the crop drops its last few rows/columns (fewer than the factor, so under one output
        # pixel), split between the two sides.
        f = max(1, min(h // out_hw[0], w // out_hw[1]))
        ch, cw = h - h % f, w - w % f
        self.box = (x + (w - cw) // 2, y + (h - ch) // 2, cw, ch)
        self.factor = f
        mid = (ch // f, cw // f)
        self.final = mid != tuple(out_hw)
        # INTER_AREA averages every source pixel (no aliasing) when shrinking; it is not meant
        # for enlarging, where bilinear is the plain choice.
        shrink = out_hw[0] <= mid[0] and out_hw[1] <= mid[1]
        self.interp = cv2.INTER_AREA if shrink else cv2.INTER_LINEAR

    def __call__(self, frame: np.ndarray, unit: tuple[float, float],
                 mask: np.ndarray | None) -> np.ndarray:
        x, y, w, h = self.box
        f = frame[y:y + h, x:x + w]
        if f.ndim == 3 and f.shape[2] == 4:
            f = f[:, :, :3]
        if self.color:
            if f.ndim == 2:
                f = np.repeat(f[:, :, None], 3, axis=2)
        elif f.ndim == 3:
            f = cv2.cvtColor(f, cv2.COLOR_BGR2GRAY if self.order == "BGR" else cv2.COLOR_RGB2GRAY)
        scale, offset = unit
        # Float before the resize: averaging many source pixels keeps sub-level detail that an
        # 8-bit resize would round away (faint intensity changes are a signal here).
        g = f.astype(np.float32)
        if offset:
            g -= np.float32(offset)
        if scale != 1.0:
            g *= np.float32(scale)
        if mask is not None:
            g *= mask if g.ndim == 2 else mask[:, :, None]
        if self.factor > 1:
            g = cv2.resize(g, (g.shape[1] // self.factor, g.shape[0] // self.factor),
                           interpolation=cv2.INTER_AREA)
        if self.final:
            g = cv2.resize(g, (self.out_hw[1], self.out_hw[0]), interpolation=self.interp)
        np.clip(g, 0.0, 1.0, out=g)
        if g.ndim == 2:
            return g[None]
        # BGR -> RGB on the small frame: a channel permutation commutes with the resize
        return g.transpose(2, 0, 1)[::-1] if self.order == "BGR" else g.transpose(2, 0, 1)


class _NoBar:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


def _progress(on: bool, total: int | None, name: str):
    if not on:
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, desc=f"reading {name}", unit="frame", leave=False)
