"""Reading and preprocessing videos, folders of images and .npy arrays (fitode.video)."""
from __future__ import annotations

import hashlib
import math
import struct
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from fitode.errors import FitodeError
from fitode.video import Clip, VideoError, parse_roi, parse_size, parse_stride, read_video
from fitode.video.sources import container_fps_problem

H, W = 30, 40
SQ = 6  # side of the moving square


def square_x(i: int) -> int:
    return 3 + 2 * i


def square_frames(n: int, bgr: tuple[int, int, int] = (255, 255, 255)) -> np.ndarray:
    """(n, H, W, 3) uint8 BGR frames: a bright square moving right by 2 pixels per frame."""
    out = np.zeros((n, H, W, 3), np.uint8)
    for i in range(n):
        x = square_x(i)
        out[i, 12:12 + SQ, x:x + SQ] = bgr
    return out


def write_video(path: Path, frames: np.ndarray, fps: float = 25.0, fourcc: str = "mp4v") -> Path:
    h, w = frames.shape[1:3]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (w, h))
    assert writer.isOpened(), f"OpenCV cannot write {fourcc} into {path.suffix}"
    for f in frames:
        writer.write(f if f.ndim == 3 else cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
    writer.release()
    return path


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def centroid_x(frame: np.ndarray) -> float:
    col = np.clip(frame - 0.5, 0, None).sum(axis=0)
    return float((col * np.arange(frame.shape[-1])).sum() / col.sum())


@pytest.fixture(scope="module")
def videos(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("videos")
    frames = square_frames(12)
    return {
        "mp4": write_video(d / "sq.mp4", frames, fourcc="mp4v"),
        "avi": write_video(d / "sq.avi", frames, fourcc="MJPG"),
        "mov": write_video(d / "sq.mov", frames, fourcc="mp4v"),
        "mkv": write_video(d / "sq.mkv", frames, fourcc="MJPG"),
    }


# ----------------------------------------------------------------------------- formats

@pytest.mark.parametrize("fmt", ["mp4", "avi", "mov", "mkv"])
def test_reads_each_container(videos, fmt):
    clip = read_video(videos[fmt], stride=1)
    assert isinstance(clip, Clip)
    assert clip.frames.shape == (12, 1, H, W) and clip.frames.dtype == np.float32
    assert 0.0 <= clip.frames.min() and clip.frames.max() <= 1.0
    assert clip.fps == pytest.approx(25.0) and clip.fps_source == "container"
    assert clip.kind == "video" and clip.source_size == (H, W) and clip.n_source_frames == 12
    assert clip.sha256 == sha(videos[fmt])
    assert clip.dt == pytest.approx(1 / 25)
    # the square is where it was drawn (lossy codecs: within a pixel)
    for i, f in enumerate(clip.frames[:, 0]):
        assert centroid_x(f) == pytest.approx(square_x(i) + (SQ - 1) / 2, abs=1.0)


def test_folder_of_images_natural_order(tmp_path):
    for i in range(1, 13):  # f1 .. f12: a plain sort would put f10 before f2
        cv2.imwrite(str(tmp_path / f"f{i}.png"), np.full((H, W), 20 * i, np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    clip = read_video(tmp_path, fps=10, stride=1)
    assert clip.kind == "images" and clip.fps_source == "user"
    assert clip.frames.shape == (12, 1, H, W)
    np.testing.assert_allclose(clip.frames.mean(axis=(1, 2, 3)), 20 * np.arange(1, 13) / 255,
                               atol=1e-6)
    names = [f"f{i}.png" for i in range(1, 13)]
    listing = "".join(f"{n}\t{sha(tmp_path / n)}\n" for n in names)
    assert clip.sha256 == hashlib.sha256(listing.encode()).hexdigest()


def test_folder_needs_fps(tmp_path):
    cv2.imwrite(str(tmp_path / "a.png"), np.zeros((H, W), np.uint8))
    with pytest.raises(VideoError, match="--fps"):
        read_video(tmp_path)


def test_npy_gray_uint8_is_exact(tmp_path):
    rng = np.random.default_rng(0)
    arr = rng.integers(0, 256, (9, H, W), dtype=np.uint8)
    np.save(tmp_path / "a.npy", arr)
    clip = read_video(tmp_path / "a.npy", fps=50, stride=1)
    assert clip.kind == "npy" and clip.sha256 == sha(tmp_path / "a.npy")
    np.testing.assert_allclose(clip.frames[:, 0], arr / 255.0, atol=1e-6)


def test_npy_rgb_float_and_channel_order(tmp_path):
    arr = np.zeros((5, H, W, 3), np.float32)
    arr[:, :, :20, 0] = 1.0  # red on the left, RGB order as numpy users write it
    np.save(tmp_path / "rgb.npy", arr)
    clip = read_video(tmp_path / "rgb.npy", fps=50, stride=1, color=True)
    assert clip.frames.shape == (5, 3, H, W)
    np.testing.assert_allclose(clip.frames[:, 0, :, :20], 1.0)
    np.testing.assert_allclose(clip.frames[:, 1:], 0.0)
    gray = read_video(tmp_path / "rgb.npy", fps=50, stride=1)
    assert gray.frames.shape == (5, 1, H, W)
    np.testing.assert_allclose(gray.frames[:, 0, :, :20], 0.299, atol=1e-3)  # ITU-R 601 luma


def test_npy_float_out_of_range_is_rescaled(tmp_path):
    arr = np.linspace(-2.0, 6.0, 4 * H * W).reshape(4, H, W, 1)
    np.save(tmp_path / "f.npy", arr)
    clip = read_video(tmp_path / "f.npy", fps=5, stride=1)
    np.testing.assert_allclose(clip.frames[:, 0], (arr[..., 0] + 2) / 8, atol=1e-6)
    assert any("rescaled" in n for n in clip.notes)


def test_fps_override_wins_and_is_recorded(videos):
    clip = read_video(videos["mp4"], fps=100, stride=3)
    assert clip.fps == 100 and clip.fps_source == "user" and clip.fps_container == pytest.approx(25)
    assert clip.dt == pytest.approx(3 / 100)
    text = "\n".join(clip.describe())
    assert "given by --fps" in text and "container says 25" in text


def _patch_avi_rate(src: Path, dst: Path, rate: int) -> Path:
    data = bytearray(src.read_bytes())
    i = data.find(b"strh")
    struct.pack_into("<II", data, i + 8 + 20, 1, rate)  # dwScale, dwRate of the video stream
    dst.write_bytes(bytes(data))
    return dst


@pytest.mark.parametrize("rate", [50000, 90000])
def test_absurd_container_fps_asks_for_fps(videos, tmp_path, rate):
    bad = _patch_avi_rate(videos["avi"], tmp_path / "bad.avi", rate)
    with pytest.raises(VideoError, match="--fps") as info:
        read_video(bad)
    assert str(rate) in str(info.value)
    assert read_video(bad, fps=30, stride=1).frames.shape == (12, 1, H, W)


def test_time_base_as_fps_is_refused(tmp_path):
    p = write_video(tmp_path / "tb.mkv", square_frames(5), fps=1000, fourcc="MJPG")
    with pytest.raises(VideoError, match="time base"):
        read_video(p)
    assert read_video(p, fps=1000, stride=1).fps == 1000


@pytest.mark.parametrize("v", [None, float("nan"), float("inf"), 0.0, -1.0, 10001.0, 90000.0])
def test_container_fps_problems(v):
    assert container_fps_problem(v) is not None


@pytest.mark.parametrize("v", [25.0, 29.97, 59.94, 120.0, 240.0, 960.0, 5000.0])
def test_container_fps_plausible(v):
    assert container_fps_problem(v) is None


# ----------------------------------------------------------------------------- trim, crop, size

@pytest.fixture
def ramp_npy(tmp_path) -> tuple[Path, np.ndarray]:
    rng = np.random.default_rng(1)
    arr = rng.integers(0, 256, (50, H, W), dtype=np.uint8)
    np.save(tmp_path / "r.npy", arr)
    return tmp_path / "r.npy", arr


def test_trim_keeps_start_inclusive_end_exclusive(ramp_npy):
    path, arr = ramp_npy
    clip = read_video(path, fps=10, start=1.0, end=3.0, stride=1)
    assert clip.start_frame == 10 and clip.end_frame == 30 and len(clip.frames) == 20
    assert clip.n_source_frames == 50
    np.testing.assert_allclose(clip.frames[:, 0], arr[10:30] / 255, atol=1e-6)
    assert clip.times[0] == pytest.approx(1.0) and clip.times[-1] == pytest.approx(2.9)


def test_trim_video(videos):
    clip = read_video(videos["avi"], start=0.2, end=0.4, stride=1)  # frames 5..9 at 25 fps
    assert clip.start_frame == 5 and len(clip.frames) == 5
    assert centroid_x(clip.frames[0, 0]) == pytest.approx(square_x(5) + (SQ - 1) / 2, abs=1.0)


def test_end_at_exact_duration_is_allowed(ramp_npy):
    path, _ = ramp_npy
    assert len(read_video(path, fps=10, start=4.0, end=5.0, stride=1).frames) == 10


def test_roi_crops_source_pixels(ramp_npy):
    path, arr = ramp_npy
    clip = read_video(path, fps=10, roi=(5, 6, 10, 12), stride=1)
    assert clip.frames.shape == (50, 1, 12, 10) and clip.roi == (5, 6, 10, 12)
    np.testing.assert_allclose(clip.frames[:, 0], arr[:, 6:18, 5:15] / 255, atol=1e-6)


def test_default_size_short_side_and_caps(tmp_path):
    cases = {(200, 300): (64, 96), (300, 200): (96, 64), (30, 40): (30, 40),  # no upscaling
             (64, 1000): (16, 256)}  # the long side is capped at 4x the short side
    for (h, w), want in cases.items():
        np.save(tmp_path / "s.npy", np.zeros((4, h, w), np.uint8))
        assert read_video(tmp_path / "s.npy", fps=1, stride=1).size == want
    assert read_video(tmp_path / "s.npy", fps=1, stride=1, short_side=8).size == (2, 32)


def test_explicit_size_and_upscaling(ramp_npy):
    path, _ = ramp_npy
    assert read_video(path, fps=10, size=(20, 25), stride=1).frames.shape == (50, 1, 20, 25)
    assert read_video(path, fps=10, size=(60, 80), stride=1).frames.shape == (50, 1, 60, 80)


def test_resize_averages_area(tmp_path):
    rng = np.random.default_rng(2)
    arr = rng.random((3, 128, 192)).astype(np.float32)
    np.save(tmp_path / "a.npy", arr)
    clip = read_video(tmp_path / "a.npy", fps=1, stride=1)
    assert clip.size == (64, 96)
    want = arr.reshape(3, 64, 2, 96, 2).mean(axis=(2, 4))
    np.testing.assert_allclose(clip.frames[:, 0], want, atol=1e-6)
    # a non-integer factor (200 -> 64): a smooth gradient stays the same gradient
    _, xx = np.mgrid[0:200, 0:300] / np.array([200.0, 300.0])[:, None, None]
    np.save(tmp_path / "g.npy", np.stack([0.25 + 0.5 * xx] * 2).astype(np.float32))
    g = read_video(tmp_path / "g.npy", fps=1, stride=1).frames[0, 0]
    want = np.broadcast_to(0.25 + 0.5 * (np.arange(96) + 0.5) / 96, g.shape)
    np.testing.assert_allclose(g, want, atol=0.01)


def test_color_video_is_rgb(tmp_path):
    p = write_video(tmp_path / "red.avi", square_frames(4, bgr=(0, 0, 255)), fourcc="MJPG")
    clip = read_video(p, color=True, stride=1)
    assert clip.frames.shape == (4, 3, H, W) and clip.color
    inside = clip.frames[0, :, 13:17, square_x(0) + 1:square_x(0) + 5].mean(axis=(1, 2))
    assert inside[0] > 0.8 and inside[2] < 0.2  # red is channel 0


def test_explicit_stride(ramp_npy):
    path, _ = ramp_npy
    every = read_video(path, fps=10, stride=1)
    clip = read_video(path, fps=10, stride="4", start=0.3)
    assert clip.stride == 4 and clip.dt == pytest.approx(0.4)
    assert clip.stride_reason == "given by --stride"
    np.testing.assert_array_equal(clip.frame_indices, np.arange(3, 50, 4))
    np.testing.assert_array_equal(clip.frames, every.frames[3::4])


def test_auto_stride_on_a_video_records_reason(videos):
    clip = read_video(videos["mp4"])
    assert clip.stride >= 1 and clip.stride_reason.startswith("auto:")
    assert clip.dt == pytest.approx(clip.stride / clip.fps)


def test_describe_lines(videos):
    clip = read_video(videos["avi"], roi=(0, 0, 30, 20), stride=2)
    text = clip.describe()
    assert text[0].startswith("input:") and "40x30" in text[0] and "12 frames" in text[0]
    assert any(line.startswith("fps: 25 (from the container)") for line in text)
    assert any(line.startswith("frames used: 6") and "every 2nd" in line for line in text)
    assert any("30x20 pixels" in line and "gray" in line for line in text)
    assert any(line == "stride: 2 (given by --stride)" for line in text)
    assert any(line == "dt: 0.08 s" for line in text)
    # the reader's choice of track, in one line
    assert sum(line.startswith("track: the change from the static scene (its path switches") for line in text) == 1


def test_progress_bar(videos, capsys):
    read_video(videos["mp4"], progress=True, stride=1)
    assert "reading sq.mp4" in capsys.readouterr().err


# ----------------------------------------------------------------------------- mask

def test_mask_image_multiplies_before_resize(tmp_path):
    arr = np.full((3, 128, 128), 200, np.uint8)
    np.save(tmp_path / "c.npy", arr)
    mask = np.zeros((128, 128), np.uint8)
    mask[:, :64] = 255
    mask[::2, 64:] = 255  # every other row: after 2x2 averaging, half the brightness
    cv2.imwrite(str(tmp_path / "m.png"), mask)
    clip = read_video(tmp_path / "c.npy", fps=1, stride=1, mask=tmp_path / "m.png")
    assert clip.size == (64, 64) and clip.mask == str(tmp_path / "m.png")
    np.testing.assert_allclose(clip.frames[:, 0, :, :32], 200 / 255, atol=1e-6)
    np.testing.assert_allclose(clip.frames[:, 0, :, 32:], 100 / 255, atol=1e-6)


def test_mask_is_resized_and_cropped_with_roi(videos, tmp_path):
    small = np.zeros((15, 20), np.uint8)
    small[:, 10:] = 255  # right half
    cv2.imwrite(str(tmp_path / "half.png"), small)
    plain = read_video(videos["avi"], stride=1, roi=(10, 0, 30, 30))
    clip = read_video(videos["avi"], stride=1, roi=(10, 0, 30, 30), mask=tmp_path / "half.png")
    assert any("mask resized" in n for n in clip.notes)
    np.testing.assert_allclose(clip.frames[..., :9], 0.0, atol=1e-6)  # source columns 10..18
    np.testing.assert_allclose(clip.frames[..., 11:], plain.frames[..., 11:], atol=1e-6)


def test_mask_video_and_npy(videos, tmp_path):
    m = np.zeros((12, H, W, 3), np.uint8)
    for i in range(12):
        m[i, :, : 3 * i + 1] = 255  # a growing window, frame by frame
    mpath = write_video(tmp_path / "m.avi", m, fourcc="MJPG")
    np.save(tmp_path / "m.npy", (m[..., 0] > 127).astype(np.uint8))
    plain = read_video(videos["avi"], stride=1)
    for mask in (mpath, tmp_path / "m.npy"):
        clip = read_video(videos["avi"], stride=3, mask=mask)
        for j, i in enumerate(clip.frame_indices):
            np.testing.assert_allclose(clip.frames[j, 0, :, 3 * i + 3:], 0.0, atol=0.05)
            keep = max(0, 3 * i - 1)
            np.testing.assert_allclose(clip.frames[j, 0, :, :keep], plain.frames[i, 0, :, :keep],
                                       atol=0.05)


def test_binary_label_mask_png(tmp_path):
    np.save(tmp_path / "c.npy", np.full((2, H, W), 255, np.uint8))
    label = np.zeros((H, W), np.uint8)
    label[:, 20:] = 1  # a 0/1 label image, not 0/255
    cv2.imwrite(str(tmp_path / "label.png"), label)
    clip = read_video(tmp_path / "c.npy", fps=1, stride=1, mask=tmp_path / "label.png")
    np.testing.assert_allclose(clip.frames[..., 20:], 1.0)
    np.testing.assert_allclose(clip.frames[..., :20], 0.0)


def test_mask_video_too_short(videos, tmp_path):
    short = write_video(tmp_path / "m.avi", np.full((5, H, W, 3), 255, np.uint8), fourcc="MJPG")
    with pytest.raises(VideoError, match="only 5 frames"):
        read_video(videos["avi"], mask=short)


# ----------------------------------------------------------------------------- errors

def test_parsers_accept():
    assert parse_roi(" 1, 2,3 ,4") == (1, 2, 3, 4)
    # typed WxH (width first, like 640x480), returned (H, W) like the frames' shape
    assert parse_size("64x32") == (32, 64) and parse_size("64X32") == (32, 64)
    assert parse_size(" 640 × 480 ") == (480, 640)
    assert parse_stride("auto") == "auto" and parse_stride("AUTO") == "auto"
    assert parse_stride("3") == 3 and parse_stride(5) == 5


@pytest.mark.parametrize("call", [
    lambda: parse_roi("1,2,3"), lambda: parse_roi("a,b,c,d"), lambda: parse_roi("1,2,0,4"),
    lambda: parse_roi("-1,2,3,4"), lambda: parse_roi("1.5,2,3,4"),
    lambda: parse_size("64"), lambda: parse_size("0x10"), lambda: parse_size("axb"),
    lambda: parse_size("-4x5"),
    lambda: parse_stride("0"), lambda: parse_stride("-2"), lambda: parse_stride("fast"),
    lambda: parse_stride("2.5"),
])
def test_bad_flags(call):
    with pytest.raises(VideoError) as info:
        call()
    assert "\n" not in str(info.value) and str(info.value).startswith("--")


def test_argparse_flags(videos):
    import argparse

    from fitode.video import add_video_arguments, video_kwargs

    parser = argparse.ArgumentParser()
    add_video_arguments(parser)
    args = parser.parse_args(["--fps", "50", "--roi", "0,0,20,10", "--size", "10x5", "--stride",
                              "2", "--start", "0.04", "--color"])
    clip = read_video(videos["avi"], **video_kwargs(args))
    assert clip.frames.shape == (5, 3, 5, 10) and clip.fps == 50 and clip.start_frame == 2
    assert video_kwargs(parser.parse_args([]))["stride"] == "auto"
    with pytest.raises(VideoError, match="--roi"):  # propagates as the CLI's one-line error
        parser.parse_args(["--roi", "1,2"])


def _errors(tmp: Path, videos: dict[str, Path]) -> dict[str, tuple]:
    (tmp / "text.mp4").write_text("this is not a video\n")
    (tmp / "empty").mkdir()
    (tmp / "only_text").mkdir()
    (tmp / "only_text" / "a.txt").write_text("x")
    write_video(tmp / "zero.avi", np.zeros((0, H, W, 3), np.uint8), fourcc="MJPG")
    np.save(tmp / "flat.npy", np.zeros((4, 5)))
    np.save(tmp / "five.npy", np.zeros((4, 5, 6, 5)))
    np.save(tmp / "nan.npy", np.full((4, 5, 6), np.nan))
    np.save(tmp / "obj.npy", np.array([None, 1], dtype=object), allow_pickle=True)
    (tmp / "junk.npy").write_bytes(b"junk")
    (tmp / "bad.png").write_text("not a png")
    (tmp / "badimg").mkdir()
    (tmp / "badimg" / "1.png").write_text("not a png")
    cv2.imwrite(str(tmp / "badimg" / "0.png"), np.zeros((H, W), np.uint8))
    (tmp / "sizes").mkdir()
    cv2.imwrite(str(tmp / "sizes" / "0.png"), np.zeros((H, W), np.uint8))
    cv2.imwrite(str(tmp / "sizes" / "1.png"), np.zeros((H + 1, W), np.uint8))
    v = videos["avi"]
    return {
        "missing file": (tmp / "nope.mp4", {}, "no such file"),
        "not a video": (tmp / "text.mp4", {}, "cannot read it as a video"),
        "zero frames": (tmp / "zero.avi", {}, "no frame could be decoded"),
        "empty folder": (tmp / "empty", {"fps": 10}, "holds no images"),
        "folder without images": (tmp / "only_text", {"fps": 10}, "holds no images"),
        "unreadable image": (tmp / "badimg", {"fps": 10, "stride": 1}, "cannot read this image"),
        "images of different sizes": (tmp / "sizes", {"fps": 10, "stride": 1}, "unlike the first"),
        "npy without fps": (tmp / "nan.npy", {}, "--fps"),
        "npy bad shape": (tmp / "flat.npy", {"fps": 1}, "expected frames shaped"),
        "npy five channels": (tmp / "five.npy", {"fps": 1}, "expected frames shaped"),
        "npy nan": (tmp / "nan.npy", {"fps": 1}, "NaN"),
        "npy objects": (tmp / "obj.npy", {"fps": 1}, "not a readable .npy"),
        "npy junk": (tmp / "junk.npy", {"fps": 1}, "not a readable .npy"),
        "fps zero": (v, {"fps": 0}, "--fps"),
        "fps nan": (v, {"fps": float("nan")}, "--fps"),
        "fps text": (v, {"fps": "fast"}, "--fps"),
        "negative start": (v, {"start": -1}, "--start"),
        "nan end": (v, {"end": float("nan")}, "--end"),
        "text start": (v, {"start": "soon"}, "--start"),
        "start after end": (v, {"start": 0.3, "end": 0.2}, "before --end"),
        "start equals end": (v, {"start": 0.2, "end": 0.2}, "before --end"),
        "trim keeps nothing": (v, {"start": 0.201, "end": 0.202}, "keep no frame"),
        "start past the end": (v, {"start": 5.0}, "past the end"),
        "end past the end": (v, {"end": 5.0}, "past the end"),
        "roi outside": (v, {"roi": (30, 0, 20, 10)}, "outside"),
        "roi bad tuple": (v, {"roi": (1, 2, 3)}, "roi"),
        "roi zero width": (v, {"roi": (1, 2, 0, 3)}, "--roi"),
        "size bad": (v, {"size": (0, 5)}, "--size"),
        "stride zero": (v, {"stride": 0}, "--stride"),
        "stride text": (v, {"stride": "often"}, "--stride"),
        "short side zero": (v, {"short_side": 0}, "short side"),
        "short side text": (v, {"short_side": "big"}, "short side"),
        "mask missing": (v, {"mask": tmp / "nomask.png"}, "--mask"),
        "mask unreadable image": (v, {"mask": tmp / "bad.png"}, "--mask"),
        "mask not a video": (v, {"mask": tmp / "text.mp4"}, "--mask"),
        "mask npy bad shape": (v, {"mask": tmp / "five.npy"}, "--mask"),
    }


def test_every_error_is_one_line_video_error(tmp_path, videos):
    cases = _errors(tmp_path, videos)
    for name, (path, kwargs, fragment) in cases.items():
        with pytest.raises(VideoError) as info:
            read_video(path, **kwargs)
        msg = str(info.value)
        assert isinstance(info.value, FitodeError), name
        assert "\n" not in msg and msg.strip() == msg and msg, f"{name}: {msg!r}"
        assert fragment in msg, f"{name}: {msg!r} lacks {fragment!r}"


def test_bad_file_prints_nothing_else(tmp_path):
    """FFmpeg and OpenCV must not add their own lines to stderr (the CLI prints one line)."""
    bad = tmp_path / "bad.mp4"
    bad.write_text("not a video")
    code = ("import sys\nfrom fitode.video import read_video, VideoError\n"
            "try:\n    read_video(sys.argv[1])\nexcept VideoError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code, str(bad)], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    assert "cannot read it as a video" in out.stdout
    assert out.stderr == ""


# ----------------------------------------------------------------------------- a real clip

REAL = Path("/work/shared/realvideos/pendulum_ornament_L170.mp4")


@pytest.mark.skipif(not REAL.exists(), reason="the shared real clips are not here")
def test_real_pendulum_clip():
    clip = read_video(REAL)
    assert clip.sha256 == "ebf6d5810f7e55f269e4a1464c28b981f86c35a1f8c2c31e3d1960b652fccb0c"
    assert clip.source_size == (352, 640) and clip.n_source_frames == 305
    assert clip.fps == pytest.approx(29.75) and clip.size == (64, 116)
    # SOURCES.md: L ~ 1.7 m, so T = 2 pi sqrt(L/g) ~ 2.62 s (+0.4% at 15 degrees)
    period_frames = int(clip.stride_reason.split("repeat every ")[1].split()[0])
    assert period_frames / clip.fps == pytest.approx(2.62, rel=0.05)
    assert len(clip.frames) >= 100 and math.isclose(clip.dt, clip.stride / clip.fps)
