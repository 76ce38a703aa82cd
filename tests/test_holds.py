"""The whole-clip check: one set of constants must hold over both halves of a measured latent."""
from __future__ import annotations

import numpy as np

from fitode.eqparse import parse
from fitode.train.config import TrainConfig
from fitode.train.holds import one_trajectory_check, perspective_check, trajectory_fit, unbend, whole_clip_check
from fitode.train.verdict import Finding


def _fall(drag: float, n: int = 80, dt: float = 1 / 120, noise: float = 0.002, seed: int = 0) -> np.ndarray:
    """Distance fallen (m) by a ball with d'' = 9.81 - drag*d'^2, fine Euler steps, plus noise."""
    rng = np.random.default_rng(seed)
    d, v, out = 0.0, 0.0, []
    for _ in range(n):
        out.append(d)
        for _ in range(100):
            v += (9.81 - drag * v * v) * dt / 100
            d += v * dt / 100
    return (np.array(out) + noise * rng.standard_normal(n))[:, None]


def test_a_clean_fall_holds_and_its_constant_comes_with_an_error():
    system, config = parse("d'' = g", free=["g"]), TrainConfig()
    x = _fall(0.0)
    values, errors = trajectory_fit(system, {}, x, 1 / 120, {"g": 5.0}, config)
    assert abs(values["g"] - 9.81) < 3 * errors["g"] and 0 < errors["g"] < 0.5
    finding, numbers = whole_clip_check(system, {}, x, 1 / 120, {"g": 9.8}, config)
    assert finding is None and len(numbers["g"]) == 4


def test_a_fall_slowed_by_the_air_does_not_hold_with_one_g():
    # a light ball (terminal velocity 4 m/s): g from its first half is far from g from its second
    system, config = parse("d'' = g", free=["g"]), TrainConfig()
    finding, numbers = whole_clip_check(system, {}, _fall(9.81 / 16), 1 / 120, {"g": 7.0}, config)
    assert finding is not None and finding.level == "ambiguous"
    assert "does not hold over the whole clip" in finding.reason
    first, _, second, _ = numbers["g"]
    assert first > second + 1


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


def test_windows_that_missed_a_slow_constant_are_named_against_one_trajectory():
    system, config = parse("d'' = g", free=["g"]), TrainConfig()
    x = _fall(0.0)
    found, numbers = one_trajectory_check(system, {}, x, 1 / 120, {"g": 9.8 * 1.1}, config)
    assert abs(numbers["g"][0] - 9.81) < 3 * numbers["g"][1]
    assert len(found) == 1 and found[0].names == ("g",) and "one trajectory" in found[0].reason
    assert one_trajectory_check(system, {}, x, 1 / 120, {"g": 9.81}, config)[0] == []
    assert Finding.from_dict(Finding("ambiguous", "slow", ("z",)).to_dict()) == Finding("ambiguous", "slow", ("z",))
