"""The perspective check: a path seen at an angle is read through the bend that makes it one
trajectory of the equation, and a path seen square on is read straight."""
from __future__ import annotations

import numpy as np
import pytest

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


def test_a_path_read_through_a_new_bend_says_the_bend_once():
    import torch

    from fitode.train.observe.base import Prepared
    from fitode.train.observe.position import PositionObservation
    seen = _seen_at_an_angle(_fall(0.0, noise=0.0)[:, 0], -0.08)
    prepared = Prepared(torch.as_tensor(seen, dtype=torch.float32).reshape(-1, 1, 1, 1), np.zeros((len(seen), 1)), 1,
                        "the reader's track")
    bend = {"c": 0.01, "middle": float(seen.mean()), "misfit": (3.0, 1.0), "bend_at_ends": 0.08}
    once = PositionObservation().reread(prepared, seen[:, None], bend, len(seen))
    twice = PositionObservation().reread(once, seen[:, None], {**bend, "misfit": (2.0, 1.0)}, len(seen))
    assert once.note.count("perspective") == twice.note.count("perspective") == 1
    assert twice.note.startswith("the reader's track;") and "2.0x better" in twice.note


def _drag_fall(t: np.ndarray, k: float = 0.2724, g: float = 9.80665) -> np.ndarray:
    vt = np.sqrt(g / k)
    return vt ** 2 / g * np.log(np.cosh(g * t / vt))


def test_a_fall_read_up_is_turned_to_run_down_as_its_equation_says():
    from fitode.eqparse.gauge import gauge_plan
    from fitode.train.direct import orientation
    system = parse("y'' = g - k*y'*abs(y')")
    t = np.arange(240) / 240
    up = -(_drag_fall(t) - 1.0) / 1.5  # the reader's y runs up, in units of its own
    gauge = gauge_plan(system)
    assert gauge["y"].scale_learned
    assert list(orientation(system, {}, up[:, None], 1 / 240, {"k": 1.0}, gauge=gauge)) == [-1.0]
    assert list(orientation(system, {}, -up[:, None], 1 / 240, {"k": 1.0}, gauge=gauge)) == [1.0]


@pytest.mark.slow
@pytest.mark.long
def test_a_fall_with_strong_drag_gives_k_side_on_and_no_perspective_bend(tmp_path):
    import fitode
    from fitode.synth import scene, write_video

    v = scene("drag_fall", 0.2724, fps=240, size=(240, 60), seed=0)
    y, dt = v.state[:, 0], v.dt
    i, j = 12, len(y) - 12
    res = fitode.fit(str(write_video(v, tmp_path / "drag.mp4")), eq="y'' = g - k*y'*abs(y')", restarts=2,
                     progress=False, calibrate=f"y({i * dt:.5f})={y[i]:.5f}; y({j * dt:.5f})={y[j]:.5f}")
    # before: the path read up (y up) had no one trajectory with a positive scale, k = -0.003
    assert res.values["k"] == pytest.approx(0.2724, rel=0.10)
    assert not res.checks["perspective"]["apply"]


def test_a_bend_no_camera_makes_is_not_applied():
    # a throw's flight and the rest after its landing, one stretch: a bend of 0.75 at the ends fits
    # them better than none, and the path read through it gave g 0.13 for 19.2
    system, config = parse("y'' = -g", free=["g"]), TrainConfig()
    dt = 1 / 240
    t = np.arange(48) * dt
    flight = 2.0 + 250.0 * t - 0.5 * 10400.0 * t ** 2
    x = np.concatenate([flight, np.full(20, flight[-1])]) + 0.01 * np.random.default_rng(0).standard_normal(68)
    found = perspective_check(system, {}, x[:, None], dt, {"g": 1.0}, config)
    assert found["bend_at_ends"] > 0.5 and found["misfit"][1] < found["misfit"][0]
    assert not found["apply"]
