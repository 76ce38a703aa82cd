"""The perspective check: a path seen at an angle is read through the bend that makes it one
trajectory of the equation, and a path seen square on is read straight."""
from __future__ import annotations

import numpy as np

from fitode.eqparse import parse
from fitode.train.config import TrainConfig
from fitode.train.perspective import perspective_check, unbend

from test_consistency import _fall


def _seen_at_an_angle(d: np.ndarray, bend: float) -> np.ndarray:
    """Positions d as a camera that looks at their line at an angle reads them: a homography
    about their middle that bends the ends by `bend`."""
    m = d.mean()
    return m + (d - m) / (1 + bend / np.abs(d - m).max() * (d - m))


def test_a_fall_seen_at_an_angle_is_read_through_the_perspective():
    system, config = parse("d'' = g", free=["g"]), TrainConfig()
    seen = _seen_at_an_angle(_fall(0.0, noise=0.0005)[:, 0], -0.08)[:, None]
    found = perspective_check(system, {}, seen, 1 / 120, {"g": 7.0}, config)
    straight, bent = found["constants"]["g"]
    assert found["apply"] and 0.06 < found["bend_at_ends"] < 0.10
    assert found["misfit"][1] < found["misfit"][0] / 3
    # bent back, the reading is affine in the distance fallen, so one affine calibration gives g
    back = unbend(seen[:, 0], found["c"], found["middle"])
    slope = np.polyfit(back, _fall(0.0, noise=0.0)[:, 0], 1)[0]
    assert abs(bent * slope / 9.81 - 1) < 0.01
    assert abs(straight * np.polyfit(seen[:, 0], _fall(0.0, noise=0.0)[:, 0], 1)[0] / 9.81 - 1) > 0.05


def test_a_fall_seen_square_on_is_read_straight():
    system, config = parse("d'' = g", free=["g"]), TrainConfig()
    found = perspective_check(system, {}, _fall(0.0), 1 / 120, {"g": 7.0}, config)
    assert not found["apply"] and found["bend_at_ends"] < 0.01


def test_a_bend_whose_pole_falls_inside_the_frames_is_refused():
    x = np.linspace(-1.0, 1.0, 21)
    assert unbend(x, 0.5, 0.0) is not None
    assert unbend(x, 1.2, 0.0) is None  # 1 + c (x - m) reaches zero at x = -0.83
