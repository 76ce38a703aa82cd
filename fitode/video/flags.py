"""The video options: parsing what a user types (--roi, --size, --stride), checking what a
caller passes to `read_video`, and the argparse flags shared by every command that reads video.

Sizes are typed WxH, width first, the way resolutions are written (640x480); in Python they are
(H, W) tuples, numpy's order, like the frames' shape.
"""
from __future__ import annotations

import math
import re

from fitode.video.clip import VideoError

_SIZE = re.compile(r"\s*(\d+)\s*[xX×*]\s*(\d+)\s*")


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
    """'WxH' (width first: '640x480') -> (H, W), numpy's order."""
    m = _SIZE.fullmatch(str(text))
    if not m:
        raise VideoError(f"--size expects WIDTHxHEIGHT in pixels, such as 640x480; got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
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
    argparse parser, parsed on the spot; `video_kwargs(args)` turns them into read_video's
    keywords."""
    g = parser.add_argument_group("video")
    g.add_argument("--fps", type=float, default=None, metavar="F",
                   help="real frame rate; always wins over the file's (slow-motion clips report "
                        "their playback rate; folders of images and .npy arrays need it)")
    g.add_argument("--start", type=float, default=None, metavar="S", help="first second to use")
    g.add_argument("--end", type=float, default=None, metavar="S", help="second to stop at")
    g.add_argument("--roi", type=parse_roi, default=None, metavar="X,Y,W,H",
                   help="crop, in pixels of the source frame (x right, y down)")
    g.add_argument("--size", type=parse_size, default=None, metavar="WxH",
                   help="resize to W pixels wide by H high, e.g. 64x48 (default: aspect kept, "
                        "short side 64, long side at most 256)")
    g.add_argument("--color", action="store_true", help="keep RGB channels (default gray)")
    g.add_argument("--stride", type=parse_stride, default="auto", metavar="K|auto",
                   help="use every K-th frame (dt = K/fps); auto picks it from how much frames "
                        "change (default)")
    g.add_argument("--mask", default=None, metavar="PATH",
                   help="mask image or video multiplied with the frames (black hides, white keeps)")


def video_kwargs(args) -> dict:
    """read_video keywords from the flags that `add_video_arguments` added."""
    return {k: getattr(args, k) for k in
            ("fps", "start", "end", "roi", "size", "color", "stride", "mask")}


# read_video's keywords come from Python callers too, not only from the parsers above; their
# errors name the flag, since that is how most users met the option.

def check_roi(roi) -> tuple[int, int, int, int]:
    try:
        x, y, w, h = (int(v) for v in roi)
    except (TypeError, ValueError):
        raise VideoError(f"roi must be (x, y, w, h) in pixels; got {roi!r}") from None
    return parse_roi(f"{x},{y},{w},{h}")


def check_size(size) -> tuple[int, int]:
    """(H, W) -> (H, W), checked."""
    try:
        h, w = (int(v) for v in size)
    except (TypeError, ValueError):
        raise VideoError(f"size must be (H, W) in pixels; got {size!r}") from None
    if h < 1 or w < 1:
        raise VideoError(f"--size: both sides must be at least 1 pixel; got (H, W) = {(h, w)}")
    return h, w


def check_stride(stride) -> int | str:
    if isinstance(stride, int) and not isinstance(stride, bool):
        if stride < 1:
            raise VideoError(f"--stride must be at least 1; got {stride}")
        return stride
    return parse_stride(stride)


def check_fps(fps) -> float | None:
    if fps is None:
        return None
    try:
        v = float(fps)
    except (TypeError, ValueError):
        raise VideoError(f"--fps expects a number of frames per second; got {fps!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise VideoError(f"--fps must be a positive number of frames per second; got {fps}")
    return v


def check_seconds(name: str, value) -> float | None:
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v) or v < 0:
        raise VideoError(f"{name} must be a time in seconds >= 0; got {value!r}")
    return v
