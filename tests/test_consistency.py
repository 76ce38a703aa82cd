"""The consistency checks: one set of constants must hold over both halves of a measured latent,
and agree with one trajectory over the whole clip."""
from __future__ import annotations

import numpy as np

from fitode.eqparse import parse
from fitode.train.config import TrainConfig
from fitode.train.consistency import one_trajectory_check, whole_clip_check
from fitode.train.trajectory import fit_trajectory
from fitode.train.findings import Finding


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
    fitted = fit_trajectory(system, {}, x, 1 / 120, {"g": 5.0})
    assert abs(fitted.values["g"] - 9.81) < 3 * fitted.errors["g"] and 0 < fitted.errors["g"] < 0.5
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


def test_windows_that_missed_a_slow_constant_are_named_against_one_trajectory():
    system, config = parse("d'' = g", free=["g"]), TrainConfig()
    x = _fall(0.0)
    found, numbers = one_trajectory_check(system, {}, x, 1 / 120, {"g": 9.8 * 1.1}, config)
    assert abs(numbers["g"][0] - 9.81) < 3 * numbers["g"][1]
    assert len(found) == 1 and found[0].names == ("g",) and "one trajectory" in found[0].reason
    assert one_trajectory_check(system, {}, x, 1 / 120, {"g": 9.81}, config)[0] == []
    assert Finding.from_dict(Finding("ambiguous", "slow", ("z",)).to_dict()) == Finding("ambiguous", "slow", ("z",))


def _swing(theta0_deg: float, n: int = 150, dt: float = 1 / 30, noise: float = 0.001, seed: int = 0) -> np.ndarray:
    """A damped sine pendulum's angle (L = 0.5 m, zeta = 0.3/s), fine RK4 steps, plus noise."""
    from scipy.integrate import solve_ivp
    t = np.arange(n) * dt
    sol = solve_ivp(lambda _, y: [y[1], -9.80665 / 0.5 * np.sin(y[0]) - 0.3 * y[1]], (0, t[-1]),
                    [np.radians(theta0_deg), 0.0], t_eval=t, rtol=1e-10, atol=1e-12)
    return (sol.y[0] + noise * np.random.default_rng(seed).standard_normal(n))[:, None]


def test_a_linear_pendulum_on_a_large_swing_does_not_hold_where_it_is_right_on_a_small_one():
    # the linear equation's L drifts with the amplitude: 50 degrees decaying to 10 in 5 s gives
    # halves a few percent apart, under the 5% a constant may move but far beyond its errors
    linear = parse("theta'' = -9.80665/L*theta - zeta*theta'")
    config = TrainConfig()
    finding, numbers = whole_clip_check(linear, {}, _swing(50), 1 / 30, {"L": 0.5, "zeta": 0.3}, config)
    assert finding is not None and "does not hold over the whole clip" in finding.reason, numbers
    assert "L" in finding.names  # the constants whose halves disagree, each
    first, _, second, _ = numbers["L"]
    assert 0.02 < abs(first / second - 1) < 0.05  # the case the 5% tolerance let through
    assert whole_clip_check(linear, {}, _swing(4), 1 / 30, {"L": 0.5, "zeta": 0.3}, config)[0] is None
    sine = parse("theta'' = -9.80665/L*sin(theta) - zeta*theta'")
    assert whole_clip_check(sine, {}, _swing(50), 1 / 30, {"L": 0.5, "zeta": 0.3}, config)[0] is None
