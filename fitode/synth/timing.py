"""Clips whose frame times are not a constant rate: the container's timestamps written as given.

    fine = render_equation(..., dt=1/600)              # the motion, finely sampled
    t = phone_times(300, 30.0, jitter=0.08, drops=4)   # capture times as a phone writes them
    write_timed(sample_at(fine, t), t, "vfr.mp4")       # frames at those times, stamped with them
    write_timed(pulldown(sample_at(fine, np.arange(240) / 24)), np.arange(300) / 30, "pd.mp4")

Written with PyAV (libx264, time base 1/90000), so that the stamps are the times asked for to
11 microseconds; OpenCV's own writer knows one constant rate only.
"""
from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np

from fitode.errors import FitodeError
from fitode.synth.video import SynthVideo

TIME_BASE = Fraction(1, 90000)


def sample_at(v: SynthVideo, times: np.ndarray) -> np.ndarray:
    """The frames of a finely sampled video nearest to each time (seconds from its first frame);
    render it at least ten times finer than the intervals asked for."""
    idx = np.rint(np.asarray(times, np.float64) / v.dt).astype(np.int64)
    if idx.min() < 0 or idx.max() >= v.n_frames:
        raise FitodeError(f"times {times.min():.4g} to {times.max():.4g} s lie outside the video "
                          f"(0 to {(v.n_frames - 1) * v.dt:.4g} s)")
    return v.frames[idx]


def pulldown(frames: np.ndarray, every: int = 4) -> np.ndarray:
    """24 -> 30 fps the simple way (what a frame-rate conversion writes): after every `every`
    frames the last one is shown again."""
    out = []
    for i, f in enumerate(frames):
        out.append(f)
        if i % every == every - 1:
            out.append(f)
    return np.stack(out)


def phone_times(n: int, fps: float, *, jitter: float = 0.08, drops: int = 0, seed: int = 0) -> np.ndarray:
    """n capture times as a phone stamps them: the nominal interval with a jitter of `jitter`
    intervals (standard deviation, each frame on its own), and `drops` frames the encoder let
    fall (a gap of two intervals), at random places."""
    rng = np.random.default_rng(seed)
    slots = np.arange(n + drops, dtype=np.float64)
    if drops:
        gone = rng.choice(np.arange(5, n + drops - 5), size=drops, replace=False)
        slots = np.delete(slots, gone)
    t = (slots + rng.normal(0.0, jitter, n).clip(-0.4, 0.4)) / fps
    return t - t[0]


def write_timed(frames: np.ndarray, times: np.ndarray, path: str | Path, rate: float = 30.0,
                quality: int = 18, metadata: dict[str, str] | None = None) -> Path:
    """Write gray (T, H, W) or RGB (T, H, W, 3) frames (float in [0, 1] or uint8) to an mp4 whose
    frame i is stamped at times[i]; rate is the nominal rate the container records; metadata:
    container tags ({"com.android.capture.fps": "120.000000"} marks a phone's slow motion)."""
    import av

    times = np.asarray(times, np.float64)
    if len(times) != len(frames) or np.any(np.diff(times) <= 0):
        raise FitodeError("one increasing time per frame is needed")
    u8 = frames if frames.dtype == np.uint8 else np.clip(np.asarray(frames) * 255 + 0.5, 0, 255).astype(np.uint8)
    if u8.ndim == 3:
        u8 = np.repeat(u8[..., None], 3, axis=3)
    h, w = u8.shape[1:3]
    path = Path(path)
    with av.open(str(path), "w", options={"movflags": "use_metadata_tags"}) as out:
        out.metadata.update(metadata or {})
        stream = out.add_stream("libx264", rate=Fraction(rate).limit_denominator(100000))
        stream.width, stream.height, stream.pix_fmt = w - w % 2, h - h % 2, "yuv420p"
        stream.codec_context.time_base = TIME_BASE
        stream.options = {"crf": str(quality)}
        ticks = np.rint((times - times[0]) / float(TIME_BASE)).astype(np.int64)
        for f, tick in zip(u8, ticks):
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(f[: h - h % 2, : w - w % 2]), format="rgb24")
            frame.pts, frame.time_base = int(tick), TIME_BASE
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return path
