"""The one trajectory fitter: constants (and starting state) to a fixed trajectory, whole or in
windows, with standard errors; any number of states."""
from __future__ import annotations

import numpy as np
import pytest

from fitode.eqparse import parse
from fitode.train.trajectory import fit_trajectory, trajectory_misfit

from test_consistency import _fall


def _damped(n: int = 240, dt: float = 0.05, w2: float = 4.0, c: float = 0.3, noise: float = 0.0, seed: int = 0):
    """x' = v, v' = -w2*x - c*v from (1, 0), fine RK4 steps: both states measured, (n, 2)."""
    def f(y):
        return np.array([y[1], -w2 * y[0] - c * y[1]])
    y, out, h = np.array([1.0, 0.0]), [], dt / 20
    for _ in range(n):
        out.append(y.copy())
        for _ in range(20):
            k1 = f(y)
            k2 = f(y + h / 2 * k1)
            k3 = f(y + h / 2 * k2)
            k4 = f(y + h * k3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return np.array(out) + noise * np.random.default_rng(seed).standard_normal((n, 2))


def test_two_measured_states_give_both_constants_with_errors():
    system = parse("x' = v; v' = -w2*x - c*v")
    x = _damped(noise=0.003)
    for windows in (None, 30):
        fitted = fit_trajectory(system, {}, x, 0.05, {"w2": 3.0, "c": 0.5}, windows=windows)
        assert fitted is not None and fitted.residuals.shape[-1] == 2
        assert fitted.values["w2"] == pytest.approx(4.0, rel=0.01)
        assert fitted.values["c"] == pytest.approx(0.3, rel=0.05)
        assert 0 < fitted.errors["c"] < 0.05 and abs(fitted.values["c"] - 0.3) < 4 * fitted.errors["c"]


def test_windows_and_the_whole_trajectory_agree_on_clean_data():
    system = parse("d'' = g", free=["g"])
    x = _fall(0.0, noise=0.0)
    whole = fit_trajectory(system, {}, x, 1 / 120, {"g": 5.0})
    windows = fit_trajectory(system, {}, x, 1 / 120, {"g": 5.0}, windows=20)
    assert whole.converged and windows.windows == 20 and whole.start.shape[1] == 1
    assert whole.values["g"] == pytest.approx(9.81, rel=1e-3)
    assert windows.values["g"] == pytest.approx(whole.values["g"], rel=2e-3)
    assert whole.misfit < 1e-4 and windows.misfit < 1e-4


def test_a_windows_fit_is_the_same_on_an_affine_image_of_the_trajectory():
    # the calibration's premise: the windows' constant of x'' = a moves exactly by the map's scale
    system = parse("x'' = a")
    x = _fall(0.0, noise=0.002)
    z = fit_trajectory(system, {}, x, 1 / 120, {"a": 5.0}, windows=20)
    image = fit_trajectory(system, {}, 250.0 * x - 40.0, 1 / 120, {"a": 5.0}, windows=20)
    assert image.values["a"] == pytest.approx(250.0 * z.values["a"], rel=1e-6)


def test_soft_l1_keeps_a_few_outlying_frames_from_moving_the_constant():
    system = parse("d'' = g", free=["g"])
    x = _fall(0.0, noise=0.001)
    x[[20, 45, 60]] += 0.05  # three frames where a tracker jumped to something else
    plain = fit_trajectory(system, {}, x, 1 / 120, {"g": 9.0})
    robust = fit_trajectory(system, {}, x, 1 / 120, {"g": 9.0}, robust=True)
    assert abs(robust.values["g"] - 9.81) < abs(plain.values["g"] - 9.81) / 2


def test_a_trajectory_outside_the_equations_domain_cannot_be_fitted():
    system = parse("h' = -k*sqrt(h)")
    x = -np.linspace(1.0, 2.0, 40)[:, None]  # negative heights: sqrt(h) is not real
    assert fit_trajectory(system, {}, x, 0.1, {"k": 0.1}) is None
    assert trajectory_misfit(system, {}, x, 0.1, {"k": 0.1}) == float("inf")


def test_a_latent_at_its_own_zero_is_fitted_with_the_gauge_the_equation_fixes():
    # Torricelli on a zero-mean latent: sqrt(h) fixes h's zero, so the offset is learned with the constants
    from fitode.eqparse.gauge import gauge_plan
    system = parse("h' = -k*sqrt(h)")
    t = np.arange(120) * 0.1
    h = (1.0 - 0.05 * t / 2) ** 2
    z = ((h - h.mean()) / h.std())[:, None]
    plan = gauge_plan(system)
    assert plan["h"].offset_learned and not plan["h"].scale_learned
    assert fit_trajectory(system, {}, z, 0.1, {"k": 0.1}, windows=20) is None  # z itself dips below zero
    fitted = fit_trajectory(system, {}, z, 0.1, {"k": 0.1}, windows=20, gauge=plan)
    assert fitted.gauge["h"]["offset"] == pytest.approx(h.mean() / h.std(), rel=0.01)
    assert fitted.values["k"] == pytest.approx(0.05 / np.sqrt(h.std()), rel=0.01)  # k moves by the scale to the 1/2


def test_segments_of_a_coarse_second_order_path_are_the_whole_trajectory():
    # a segment's state is read from its starting frames by finite differences: starting frames
    # tied to the frames of the segment before made each one another trajectory (g1 0.067% low)
    from fitode.train.trajectory import long_options
    system = parse("z'' + g1*z' + g0*z = 0")
    t = np.arange(270) * 0.2  # 16 frames a period, the paper's motion video
    z = (np.exp(-0.04 * t) * np.cos(np.sqrt(4.0016 - 0.0016) * t))[:, None]
    whole = fit_trajectory(system, {}, z, 0.2, {"g0": 4.0, "g1": 0.079}, substeps=8, solver="lm")
    pieces = fit_trajectory(system, {}, z, 0.2, {"g0": 4.0, "g1": 0.079}, substeps=8, **long_options(len(z)))
    assert whole.values["g1"] == pytest.approx(0.08, rel=1e-5)
    for n in ("g0", "g1"):
        assert pieces.values[n] == pytest.approx(whole.values[n], rel=1e-6)
    assert pieces.misfit < 1e-6


def test_levenberg_marquardt_stops_at_its_bound_and_says_it_did_not_settle(monkeypatch):
    # the bundled example read as a position (`--observe position`): a tracker that jumps between
    # two places, which no pendulum follows; the steps crept down a wrong basin for minutes. The
    # solver's work is bounded: counted here in the rollouts it asks for, not in seconds
    from fitode.codegen import PhysicsBlock
    from fitode.eqparse import ParamSpec
    from fitode.train.trajectory import TRIALS_PER_STEP, long_options
    rollouts = []
    real = PhysicsBlock.rollout_numpy
    monkeypatch.setattr(PhysicsBlock, "rollout_numpy", lambda self, *a, **k: rollouts.append(1) or real(self, *a, **k))
    system = parse("theta'' = -g/L*theta - zeta*theta'")
    params = {"L": ParamSpec(init=1.0, min=0.0), "zeta": ParamSpec(init=0.1, min=0.0)}
    x = np.array([-0.483, 0.286, 0.834, 0.923, 0.879, 0.892, 0.873, 0.178, 0.374, 0.354, 1.019, 0.927, 0.911, 0.942,
                  0.915, 0.551, 0.264, 0.757, 0.969, 0.907, 0.906, 0.869, 0.177, 0.377, 0.35, 0.951, 0.94, 0.946,
                  0.967, 0.889, 0.346, -0.629, -1.171, -1.491, -1.494, -1.497, -1.536, -1.089, -0.531])[:, None]
    bound = 12
    fit = fit_trajectory(system, params, x, 1 / 15, {"L": 0.27, "zeta": 11.5}, iterations=bound,
                         **long_options(len(x)))
    assert fit is not None and not fit.converged  # it gives up, and the record says it did not settle
    assert fit.steps <= bound and fit.rollouts <= TRIALS_PER_STEP * bound
    # every rollout is the start, a step's Jacobian (one batched rollout), a trial, or the summary's few
    assert len(rollouts) <= 1 + fit.steps + fit.rollouts + 4


def test_a_path_shorter_than_two_starting_contexts_is_one_trajectory():
    # a ball's third flight filmed at 30 fps is 7 frames: one segment with no join to the next, which
    # failed on the join's shape and dropped the flight
    from fitode.train.trajectory import long_options

    system = parse("y'' = -g", free=["g"])
    rng = np.random.default_rng(2)
    for n in (7, 8, 9):
        t = np.arange(n) / 30
        y = (1 + 2 * t - 4.905 * t ** 2)[:, None] + rng.normal(0, 2e-4, (n, 1))
        fit = fit_trajectory(system, {}, y, 1 / 30, {"g": 5.0}, **long_options(n))
        assert fit is not None and fit.values["g"] == pytest.approx(9.81, abs=4 * fit.errors["g"])
        assert fit.errors["g"] < 0.5
