"""The reading loop: decode, trim, preprocess and keep every stride-th frame, then a `Clip`."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fitode.stride import auto_stride
from fitode.video.clip import Clip, VideoError
from fitode.video.flags import check_fps, check_roi, check_seconds, check_size, check_stride
from fitode.video.mask import Mask
from fitode.video.preprocess import Preprocess, check_roi_inside, default_size
from fitode.video.sources import (ArraySource, Source, container_fps_problem, open_source,
                                  source_sha256)
from fitode.video.timing import FrameTimes, frame_times, resample
from fitode.video.stills import StillKeeper
from fitode.video.track import TrackRecorder


def read_video(path: str | Path, *, fps: float | None = None, start: float | None = None,
               end: float | None = None, roi: tuple[int, int, int, int] | None = None,
               size: tuple[int, int] | None = None, color: bool = False,
               stride: int | str = "auto", mask: str | Path | None = None, short_side: int = 64,
               progress: bool = False, track: bool = True) -> Clip:
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
    size: (H, W) output size, height first like the frames' shape (the --size flag is typed
        WxH; `parse_size` turns it into this). Default: scale so the short side is `short_side`
        (never upscaling, and never letting the long side exceed 4 * short_side, for very
        elongated frames).
    color: keep RGB channels (C = 3); default gray (C = 1).
    stride: keep every stride-th frame (dt = stride / fps), or "auto": see `fitode.stride`.
    mask: an image or .npy (H, W) (any size: it is resized to the source frame), or a mask
        video, folder of images or .npy (T, H, W) whose frame i multiplies source frame i. Gray
        values: 8-bit 0..255 means 0..1, but an image or array whose values all lie in [0, 1]
        (a 0/1 label mask) is used as is. Applied at source resolution, after the crop and
        before the resize.
    progress: show a progress bar on stderr.
    track: measure where the moving object is in every kept frame as they are decoded (Clip.track,
        fitode.video.track); False where the caller has it from an earlier read of the same frames.

    `sha256` is that of the file; for a folder it is the SHA-256 of the text made of one line
    per image, in the order used: the file name, a tab, the SHA-256 of its bytes.
    `n_source_frames` is exact for folders and arrays, and for a video file the number of frames
    decoded when decoding reached its end; when `end` stopped it earlier, the larger of the
    container's count and the frames seen.
    """
    p = Path(path)
    if not p.exists():
        raise VideoError(f"{path}: no such file or folder")
    fps = check_fps(fps)
    stride_arg = check_stride(stride)
    if roi is not None:
        roi = check_roi(roi)
    if size is not None:
        size = check_size(size)
    try:
        side = int(short_side)
    except (TypeError, ValueError):
        side = 0
    if side < 1:
        raise VideoError(f"the short side must be a whole number of pixels >= 1; got {short_side!r}")
    start, end = check_seconds("--start", start), check_seconds("--end", end)
    if start is not None and end is not None and start >= end:
        raise VideoError(f"--start ({start:g} s) must come before --end ({end:g} s)")

    src = open_source(p)
    try:
        return _read(p, src, fps, start, end, roi, size, bool(color), stride_arg,
                     None if mask is None else Path(mask), side, progress, bool(track))
    finally:
        src.close()


def _frame_range(fps: float, start: float | None, end: float | None) -> tuple[int, int | None]:
    # Frame i sits at i/fps; keep start <= i/fps < end. The epsilon absorbs decimal input such as
    # --start 1.0 at 29.97 fps landing a hair above an integer.
    first = max(0, math.ceil(float(start) * fps - 1e-6)) if start is not None else 0
    stop = max(0, math.ceil(float(end) * fps - 1e-6)) if end is not None else None
    return first, stop


def _read(p: Path, src: Source, fps: float | None, start, end, roi, size, color: bool,
          stride_arg: int | str, mask_path: Path | None, short_side: int, progress: bool, follow: bool = True) -> Clip:
    name = p.name or str(p)
    if fps is not None:
        fps_used, fps_source = fps, "user"
    elif src.kind != "video":
        what = "a folder of images" if src.kind == "images" else "a .npy array"
        raise VideoError(f"{name}: {what} has no frame rate; pass --fps")
    else:
        problem = container_fps_problem(src.container_fps)
        if problem:
            raise VideoError(f"{name}: the file reports {problem}; pass the real one with --fps")
        fps_used, fps_source = float(src.container_fps), "container"  # type: ignore[arg-type]

    first, stop = _frame_range(fps_used, start, end)
    if stop is not None and first >= stop:
        raise VideoError(f"--start {start:g} s and --end {end:g} s keep no frame at {fps_used:.6g} fps")
    if isinstance(src, ArraySource):
        total = src.arr.shape[0]
        if total and first < total:
            src.calibrate(first, min(total, stop) if stop is not None else total)
    sha = source_sha256(p, src)

    explicit = stride_arg if isinstance(stride_arg, int) else None
    notes: list[str] = []
    buf: np.ndarray | None = None
    kept = 0
    stamps: list[float | None] = []
    hw: tuple[int, int] | None = None
    prep: Preprocess | None = None
    the_mask: Mask | None = None
    tracker: TrackRecorder | None = None
    keeper: StillKeeper | None = None

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
            # frame 0 is always decoded: its size sets up the crop, the resize and the mask
            if i == 0 or use:
                frame = src.retrieve()
                if hw is None:
                    hw = (int(frame.shape[0]), int(frame.shape[1]))
                    crop = roi or (0, 0, hw[1], hw[0])
                    check_roi_inside(crop, hw)
                    out_hw = size or default_size(crop[3], crop[2], short_side)
                    prep = Preprocess(crop, out_hw, color, src.order)
                    tracker = TrackRecorder(prep.box, todo if todo is None else (todo - first) // (explicit or 1) + 1,
                                            src.order)
                    keeper = StillKeeper(src.order, todo if todo is None else (todo - first) // (explicit or 1) + 1)
                    if mask_path is not None:
                        the_mask = Mask(mask_path, hw, prep.box)
                        the_mask.grab()  # catch up with frame 0
                elif frame.shape[:2] != hw:
                    raise VideoError(f"{name}: frame {i} is {frame.shape[1]}x{frame.shape[0]} "
                                     f"(WxH), unlike the first frame's {hw[1]}x{hw[0]}")
                if use:
                    assert prep is not None
                    cut = the_mask.current() if the_mask is not None else None
                    small = prep(frame, src.unit(frame), cut)
                    assert tracker is not None
                    if follow:
                        tracker.add(frame, src.unit(frame), cut)
                    keeper.add(i, frame, src.unit(frame))
                    if buf is None or kept == buf.shape[0]:
                        buf = _grow(buf, kept, small.shape, todo, first, explicit)
                    buf[kept] = small
                    stamps.append(src.timestamp())
                    kept += 1
            i += 1
            bar.update(1)
    finally:
        bar.close()
        if the_mask is not None:
            the_mask.close()

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

    timing = _frame_times(buf[:kept], stamps, fps_used, fps_source, explicit)
    source = first + (explicit or 1) * np.arange(kept)  # the source index of every buffered frame
    if timing.grid is not None:
        assert timing.stamps is not None
        right = np.clip(np.searchsorted(timing.stamps, timing.grid), 1, len(timing.stamps) - 1)
        near = right - (timing.grid - timing.stamps[right - 1] < timing.stamps[right] - timing.grid)
        source = source[timing.keep][near]  # a filled-in frame: the source frame nearest its time
        buf, kept = resample(buf[timing.keep], timing.stamps, timing.grid), len(timing.grid)
        times = timing.grid
    elif len(timing.keep) < kept:
        buf, kept = buf[timing.keep], len(timing.keep)
        source = source[timing.keep]
        times = timing.stamps
    else:
        times = timing.stamps
    if timing.rate != fps_used:  # frame_times keeps the nominal rate where the stamps agree with it
        fps_used, fps_source = timing.rate, ("timestamps" if fps_source == "container" else fps_source)

    if explicit is not None:
        k, reason = explicit, "given by --stride"
    else:
        choice = auto_stride(buf[:kept], fps_used)
        k, reason = choice.stride, choice.reason
    # A view, not a copy, when every buffered frame is kept: the buffer's unused tail was never
    # written, so it holds no memory, while a copy would briefly double the frames.
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
    if isinstance(src, ArraySource) and src.note:
        notes.append(src.note)
    if the_mask is not None and the_mask.note:
        notes.append(the_mask.note)
    every = slice(0, kept, k if explicit is None else 1)
    assert tracker is not None
    # the collected frame behind every kept one (repeats dropped, a filled-in frame its nearest)
    track = tracker.finish(((source - first) // (explicit or 1))[every]) if follow else None
    kept_times = None if times is None else np.asarray(times[every])
    return Clip(frames=frames, fps=fps_used, fps_source=fps_source, stride=k, dt=k / fps_used,
                stride_reason=reason, path=str(p), sha256=sha, source_size=hw,
                n_source_frames=n_source, start_frame=first,
                end_frame=decoded if stop is None else stop, kind=src.kind,
                fps_container=src.container_fps, roi=roi, color=color,
                mask=None if mask_path is None else str(mask_path), notes=notes,
                frame_times=kept_times, timing=timing.lines, capture_fps=src.capture_fps,
                source_index=source[every] if timing.lines else None, track=track,
                stills=None if keeper is None else keeper.frames)


def _frame_times(frames: np.ndarray, stamps: list, fps: float, fps_source: str,
                 explicit: int | None) -> FrameTimes:
    """The timestamps checked (fitode.video.timing). A user's --fps is the capture rate: the stamps
    keep their pattern (repeats, holes, jitter) and are rescaled to it (slow motion)."""
    if len(stamps) < 3 or any(t is None for t in stamps):
        return FrameTimes(np.arange(len(frames)), fps)
    step = explicit or 1
    timing = frame_times(frames, np.asarray(stamps, np.float64), fps / step, consecutive=step == 1)
    if fps_source == "user":
        scale = timing.rate * step / fps  # the stamps' own capture rate over the one given
        timing.rate = fps / step
        timing.grid = None if timing.grid is None else timing.grid * scale
        timing.stamps = None if timing.stamps is None else timing.stamps * scale
        timing.lines = [line for line in timing.lines if not line.startswith("the timestamps run at")]
    timing.rate *= step  # frame_times saw every step-th frame
    return timing


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
