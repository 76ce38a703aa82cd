"""Where frames come from: a video file, a folder of images or a .npy array, read one frame at
a time, and what identifies the input (its SHA-256, its frame rate)."""
from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

import cv2
import numpy as np

from fitode.video.clip import VideoError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm",
                  ".pbm", ".pnm", ".jp2", ".exr", ".hdr")
MAX_FPS = 10000.0
# Container "frame rates" that are really time bases (Matroska/WebM 1/1000, MPEG-TS 1/90000):
# FFmpeg reports them for variable-rate files whose true rate it cannot tell.
_TIME_BASES = (1000.0, 90000.0)


class Source:
    """Sequential frames. `grab` advances (cheaply), `retrieve` returns the current frame."""

    kind = "video"
    container_fps: float | None = None
    count_hint: int | None = None
    capture_fps: float | None = None  # the rate a slow-motion clip was recorded at, from its metadata
    order = "BGR"  # channel order of 3-channel frames

    def grab(self) -> bool:
        raise NotImplementedError

    def retrieve(self) -> np.ndarray:
        raise NotImplementedError

    def unit(self, frame: np.ndarray) -> tuple[float, float]:
        """(scale, offset) so that (frame - offset) * scale lies in [0, 1]."""
        return dtype_unit(frame.dtype)

    def timestamp(self) -> float | None:
        """The container's presentation time of the frame last grabbed, in seconds (None: none)."""
        return None

    def close(self) -> None:
        pass


def open_source(p: Path) -> Source:
    """The source for a folder, a .npy file or (anything else) a video file."""
    if p.is_dir():
        return ImageSource(p)
    if p.suffix.lower() == ".npy":
        return ArraySource(p)
    return VideoSource(p)


def dtype_unit(dtype: np.dtype) -> tuple[float, float]:
    if dtype == np.uint8:
        return 1.0 / 255.0, 0.0
    if dtype == np.uint16:
        return 1.0 / 65535.0, 0.0
    return 1.0, 0.0


class VideoSource(Source):
    def __init__(self, path: Path):
        self.name = path.name
        # OpenCV logs its own warnings for files it cannot open; the VideoError below says it
        # in one line instead.
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
        self.capture_fps = capture_fps(path)

    def grab(self) -> bool:
        return bool(self.cap.grab())

    def timestamp(self) -> float | None:
        # OpenCV's position after a grab is that frame's own presentation time, edit lists applied:
        # on the clips in view it matched PyAV's packet times to the microsecond
        ms = self.cap.get(cv2.CAP_PROP_POS_MSEC)
        return ms / 1000.0 if math.isfinite(ms) else None

    def retrieve(self) -> np.ndarray:
        ok, frame = self.cap.retrieve()
        if not ok or frame is None:
            raise VideoError(f"{self.name}: a frame was found but could not be decoded")
        return frame

    def close(self) -> None:
        self.cap.release()


# Where cameras write the rate a slow-motion clip was recorded at (it plays back at the container's rate)
CAPTURE_RATE_TAGS = ("com.android.capture.fps", "com.apple.quicktime.capture.fps")


def capture_fps(path: Path) -> float | None:
    """The capture rate a slow-motion clip's metadata records (Android's com.android.capture.fps,
    Apple's capture tags), or None: no such tag, or PyAV is missing or cannot open the file."""
    try:
        import av
    except ImportError:
        return None
    try:
        with av.open(str(path)) as container:
            tags = dict(container.metadata)
            for stream in container.streams.video[:1]:
                tags.update(stream.metadata)
    except Exception:  # noqa: BLE001 - metadata is advice; OpenCV decides whether the file reads
        return None
    for key in CAPTURE_RATE_TAGS:
        try:
            value = float(tags.get(key, ""))
        except ValueError:
            continue
        if math.isfinite(value) and 0 < value <= MAX_FPS:
            return value
    return None


def _natural_key(name: str) -> list:
    return [(0, int(s), "") if s.isdigit() else (1, 0, s.lower()) for s in re.split(r"(\d+)", name)]


def _image_files(folder: Path) -> list[Path]:
    files = [p for p in folder.iterdir()
             if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in IMAGE_SUFFIXES]
    return sorted(files, key=lambda p: _natural_key(p.name))


class ImageSource(Source):
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


class ArraySource(Source):
    kind = "npy"
    order = "RGB"

    def __init__(self, path: Path):
        try:
            arr = np.load(path, mmap_mode="r", allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise VideoError(f"{path}: not a readable .npy array ({first_line(exc)})") from None
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
            self.scale_offset = (1.0, 0.0) if a.dtype == np.bool_ else dtype_unit(a.dtype)
            return
        vmin, vmax = math.inf, -math.inf
        # blocks of about 32 MB: the array is memory-mapped and may be larger than memory
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


def first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def container_fps_problem(v: float | None) -> str | None:
    """Why a container's frame rate cannot be trusted, or None when it can."""
    if v is None or not math.isfinite(v) or v <= 0:
        return "no frame rate"
    if v > MAX_FPS:
        return f"{v:.6g} fps, which is not a plausible frame rate"
    if any(abs(v - tb) < 1e-6 * tb for tb in _TIME_BASES):
        return f"{v:.6g} fps, which is a time base rather than a frame rate"
    return None


def source_sha256(p: Path, src: Source) -> str:
    """The file's SHA-256; for a folder, that of one line per image: name, tab, its SHA-256."""
    try:
        if isinstance(src, ImageSource):
            lines = "".join(f"{f.name}\t{_file_sha256(f)}\n" for f in src.files)
            return hashlib.sha256(lines.encode()).hexdigest()
        return _file_sha256(p)
    except OSError as exc:
        raise VideoError(f"{p}: cannot read it ({first_line(exc)})") from None


def _file_sha256(p: Path) -> str:
    h = hashlib.sha256()
    with open(p, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
