"""Writing synthetic videos and their ground truth.

A video `clip.mp4` (OpenCV, mp4v codec, fps = 1/dt, 8-bit BGR) or `clip.npy` (the frames
array exactly as generated) gets `clip.truth.json` beside it:

    {"format": "fitode-synth/1", "video": "clip.mp4", "generator": "paper" | "equation" | "scene",
     "equation": "...", "truth": {constant: value}, "dt": ..., "fps": ..., "n_frames": ...,
     "size": [height, width], "channels": 1 | 3, "latent_names": [...], "latent": [[...], ...],
     "settings": {generator settings: kind or scene name, seed, ...}}

mp4 is lossy (and 8-bit): use npy for the exact frames.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fitode.errors import FitodeError
from fitode.jsonio import to_jsonable
from fitode.synth.video import SynthVideo

FORMATS = {".mp4": "mp4", ".npy": "npy"}
TRUTH_FORMAT = "fitode-synth/1"


def truth_path(video_path: str | Path) -> Path:
    """Where the ground truth of a video lives: clip.mp4 -> clip.truth.json."""
    return Path(video_path).with_suffix(".truth.json")


def video_format(path: str | Path) -> str:
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise FitodeError(f"cannot tell the video format of '{path}': name it .mp4 or .npy")
    return FORMATS[suffix]


def frames_uint8(v: SynthVideo) -> np.ndarray:
    if v.frames.dtype == np.uint8:
        return v.frames
    return np.clip(np.asarray(v.frames, np.float32) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def truth_record(v: SynthVideo, video_name: str | None = None, file_format: str | None = None) -> dict:
    rec = {
        "format": TRUTH_FORMAT,
        "video": video_name,
        "file_format": file_format,
        "generator": v.meta.get("generator"),
        "equation": v.equation,
        "truth": dict(v.truth),
        "dt": v.dt,
        "fps": v.fps,
        "n_frames": v.n_frames,
        "size": list(v.size),
        "channels": v.channels,
        "frames_dtype": "uint8" if file_format == "mp4" else str(v.frames.dtype),
        "latent_names": list(v.latent_names),
        "latent": np.asarray(v.latent, np.float64).tolist(),
        "settings": v.meta,
    }
    return to_jsonable(rec)


def write_video(v: SynthVideo, path: str | Path) -> Path:
    """Write the frames (.mp4 or .npy, by the suffix) and <stem>.truth.json beside them.

    Overwrites existing files (the command line refuses unless --force). Returns the video path."""
    path = Path(path)
    fmt = video_format(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if fmt == "npy":
        np.save(path, v.frames)
    else:
        _write_mp4(v, path)
    rec = truth_record(v, path.name, fmt)
    latent = rec.pop("latent")
    # readable header, one compact line for the (long) latent series
    text = json.dumps(rec, indent=1)
    text = text[:-2] + ',\n "latent": ' + json.dumps(latent, separators=(",", ":")) + "\n}\n"
    with open(truth_path(path), "w") as fh:
        fh.write(text)
    return path


def read_truth(path: str | Path) -> dict:
    """The ground-truth record of a video (give the video's path or the JSON's)."""
    p = Path(path)
    jp = p if p.name.endswith(".truth.json") else truth_path(p)
    try:
        with open(jp) as fh:
            rec = json.load(fh)
    except FileNotFoundError:
        raise FitodeError(f"no ground truth at {jp}") from None
    except json.JSONDecodeError as exc:
        raise FitodeError(f"{jp} is not valid JSON ({exc.msg}, line {exc.lineno})") from None
    if rec.get("format") != TRUTH_FORMAT:
        raise FitodeError(f"{jp} is not a fitode synth ground-truth file")
    return rec


def _write_mp4(v: SynthVideo, path: Path) -> None:
    import cv2

    frames = frames_uint8(v)
    h, w = frames.shape[1:3]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(v.fps), (w, h), True)
    if not writer.isOpened():
        raise FitodeError(f"OpenCV cannot write an mp4 video to {path} (no mp4v encoder?); use .npy")
    try:
        for f in frames:
            writer.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR) if f.ndim == 2 else
                         np.ascontiguousarray(f[..., ::-1]))
    finally:
        writer.release()
    if not path.exists() or path.stat().st_size == 0:
        raise FitodeError(f"OpenCV wrote nothing to {path}; use .npy")
