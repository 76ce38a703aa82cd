"""bench/realclips.py's tracker on a rendered pendulum (no real clip needed) and its skip message."""
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cv2")
pytest.importorskip("scipy")

BENCH = Path(__file__).resolve().parent.parent / "bench"


def _load():
    sys.path.insert(0, str(BENCH))
    spec = importlib.util.spec_from_file_location("realclips", BENCH / "realclips.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["realclips"] = mod  # the dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _pendulum_frames(T=1.3, theta0=0.25, zeta=0.1, fps=30.0, n=180, L_px=220.0):
    """A red disc on a grey wall swinging on an arc of radius L_px about a pivot above the frame."""
    import cv2

    w0 = 2 * math.pi / T
    r = zeta / 2
    w = math.sqrt(w0 ** 2 - r ** 2)
    frames = []
    for i in range(n):
        t = i / fps
        th = theta0 * math.exp(-r * t) * math.cos(w * t)
        x, y = 160 + L_px * math.sin(th), -120 + L_px * math.cos(th)
        img = np.full((120, 320, 3), 170, np.uint8)
        cv2.circle(img, (int(round(x * 4)), int(round(y * 4))), 40, (30, 30, 200), -1, cv2.LINE_AA, shift=2)
        frames.append(img)
    return frames, fps, w0


def test_tracker_measures_the_period_of_a_rendered_pendulum():
    rc = _load()
    frames, fps, w0 = _pendulum_frames()
    tr = rc.track_colour(frames, rc.RED)
    assert np.isfinite(tr["x"]).all()
    res = rc.pendulum_truth(np.arange(len(frames)) / fps, tr["x"], tr["y"])
    # the linear oscillation's undamped period, before the finite-amplitude correction
    assert res["T_undamped"] == pytest.approx(2 * math.pi / w0, rel=5e-3)
    assert res["zeta"] == pytest.approx(0.1, abs=0.03)


def test_missing_clip_folder_is_a_skip(tmp_path, capsys):
    rc = _load()
    found, skips = rc.find_clips(tmp_path / "no-such-folder", list(rc.CLIPS))
    assert found == [] and len(skips) == 1 and skips[0].startswith("skip:")
    args = rc.argparse.Namespace(clips="pendulum_bob_L062.mp4", dir=str(tmp_path / "none"), fitode=False,
                                 fitode_timeout=1.0, check_images=None, out=str(tmp_path / "out"))
    assert rc.run(args) == 0
    assert "skip: no clip folder" in capsys.readouterr().out
    assert (tmp_path / "out" / "realclips.json").is_file()


def test_the_readings_travel_is_compared_with_the_water_top_on_the_frames_both_read(tmp_path):
    rc = _load()
    levels = np.full(40, np.nan)
    levels[5:35] = 100 + 2.0 * np.arange(30)  # the colour tracker's water top, frames 5-34
    rows = ["time_s,frame,h,y_px"] + [f"{f / 30:.4f},{f},0,{250 + 1.0 * (f - 5)}" for f in range(0, 40, 3)]
    rows[3] = rows[3].rsplit(",", 1)[0] + ","  # a frame the reading left empty
    (tmp_path / "track.csv").write_text("\n".join(rows) + "\n")
    travel = rc.reading_travel(tmp_path / "track.csv", levels)
    # frames 6, 9, ... 33 read by both, frame 6 (the emptied one) left out: a reading at half the speed
    assert travel["frames"] == 9
    assert travel["fitode_px"] == pytest.approx(24.0) and travel["tracker_px"] == pytest.approx(48.0)
    assert travel["ratio"] == pytest.approx(0.5) and travel["slope"] == pytest.approx(0.5)
    assert rc.reading_travel(tmp_path / "none.csv", levels) is None
