"""Integrators against closed forms and scipy's solve_ivp, convergence orders, and the paper's scheme."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.integrate import solve_ivp

from fitode.codegen import INTEGRATORS, PhysicsBlock, StateLayout, simulate
from fitode.codegen.integrators import SymplecticEuler, get_integrator
from fitode.codegen.errors import ParameterError
from fitode.eqparse import ParamSpec, parse

G = 9.80665
OMEGA, ZETA = 2.0, 0.04
G0, G1 = OMEGA ** 2 + ZETA ** 2, 2 * ZETA
N, DT = 100, 0.1
T = np.arange(N) * DT


def _ivp(rhs, y0):
    sol = solve_ivp(rhs, (0, T[-1]), y0, method="DOP853", t_eval=T, rtol=1e-10, atol=1e-12)
    assert sol.success
    return sol.y


# name, equation, constants, y0, reference values (N, dim)
CASES = {
    "damped": ("x'' = -g0*x - g1*x'", {"g0": G0, "g1": G1}, {"x": [1.0, -ZETA]},
               (np.exp(-ZETA * T) * np.cos(OMEGA * T))[:, None]),
    "decay": ("x' = -k*x", {"k": 0.5}, {"x": 2.0}, (2.0 * np.exp(-0.5 * T))[:, None]),
    "torricelli": ("h' = -k*sqrt(h)", {"k": 0.1}, {"h": 1.0}, ((1.0 - 0.1 * T / 2) ** 2)[:, None]),
    "freefall": ("y'' = -g", {}, {"y": [10.0, 1.0]}, (10.0 + T - G * T ** 2 / 2)[:, None]),
    "pendulum": ("theta'' = -g/L*sin(theta) - zeta*theta'", {"L": 2.0, "zeta": 0.1}, {"theta": [2.0, 0.0]},
                 _ivp(lambda t, y: [y[1], -G / 2.0 * np.sin(y[0]) - 0.1 * y[1]], [2.0, 0.0])[0][:, None]),
    "lotka": ("u' = a*u - b*u*v; v' = -c*v + d*u*v", {"a": 1.1, "b": 0.4, "c": 0.4, "d": 0.1},
              {"u": 10.0, "v": 5.0},
              _ivp(lambda t, y: [1.1 * y[0] - 0.4 * y[0] * y[1], -0.4 * y[1] + 0.1 * y[0] * y[1]], [10.0, 5.0]).T),
}


def _rel_error(name: str, integrator: str, substeps: int) -> float:
    eq, consts, y0, ref = CASES[name]
    x = simulate(parse(eq), consts, y0, N, DT, integrator, substeps).numpy()
    assert x.shape == ref.shape
    return float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))


# Measured (bench/discretisation.py): decay 2.0e-8, torricelli 3.7e-11, free fall 4e-16, Lotka-Volterra 4.5e-7.
@pytest.mark.parametrize("name", ["decay", "torricelli", "freefall", "lotka"])
def test_rk4_matches_reference_at_dt_0_1(name):
    assert _rel_error(name, "rk4", 1) < 1e-5


# The oscillators turn 0.2 rad per step at dt 0.1: RK4 measures 1.6e-4 (damped) and 7.2e-5
# (pendulum at 115 degrees) with one step per frame, 6.4e-7 and 5.0e-7 with four.
@pytest.mark.parametrize("name", ["damped", "pendulum"])
def test_rk4_oscillators(name):
    assert _rel_error(name, "rk4", 1) < 3e-4
    assert _rel_error(name, "rk4", 4) < 1e-5


def test_free_fall_is_exact_for_rk4_and_exactly_biased_for_euler():
    eq, consts, y0, ref = CASES["freefall"]
    x = simulate(parse(eq), consts, y0, N, DT, "euler").numpy()[:, 0]
    # explicit Euler: y_n = y0 + v0 t - g dt^2 n(n-1)/2
    n = np.arange(N)
    np.testing.assert_allclose(x, 10.0 + T - G * DT ** 2 * n * (n - 1) / 2, rtol=1e-12)
    assert _rel_error("freefall", "rk4", 1) < 1e-13


@pytest.mark.parametrize("integrator,order", [("euler", 1), ("symplectic", 1), ("rk4", 4)])
@pytest.mark.parametrize("name", ["damped", "lotka"])
def test_convergence_order(integrator, order, name):
    e1 = _rel_error(name, integrator, 2)
    e2 = _rel_error(name, integrator, 4)
    assert 2 ** order * 0.7 < e1 / e2 < 2 ** order * 1.4


def test_integrator_table_and_aliases():
    assert set(INTEGRATORS) == {"euler", "symplectic", "rk4"}
    assert get_integrator("paper") is SymplecticEuler
    with pytest.raises(ParameterError, match="unknown integrator"):
        get_integrator("leapfrog")


def test_symplectic_updates_highest_derivative_first_for_third_order():
    system = parse("w''' = -w - q*w'; q' = w")
    layout = StateLayout.from_system(system)
    y = torch.tensor([[0.3, -0.2, 0.5, 1.5]], dtype=torch.float64)
    h = 0.1
    step = SymplecticEuler(layout).step(lambda s: simulate_field(system)(s), y, h)[0]
    w, w1, w2, q = y[0].tolist()
    w3 = -w - q * w1
    w2n = w2 + h * w3
    w1n = w1 + h * w2n
    wn = w + h * w1n
    qn = q + h * w  # first-order variables take the plain Euler step
    np.testing.assert_allclose(step.tolist(), [wn, w1n, w2n, qn], rtol=1e-15)


def simulate_field(system):
    from fitode.codegen import compile_system
    vf = compile_system(system)
    return lambda s: vf(s)


# --------------------------------------------------------------------------- the paper's scheme
def _official_damped(z: torch.Tensor, alpha: float, beta: float, dt: float, n: int) -> torch.Tensor:
    """The official Damped_oscillation.forward (one step from two frames), iterated."""
    y0, y1 = z[..., 0], z[..., 1]
    out = [y0, y1]
    for _ in range(n - 2):
        y_hat = y1 + (y1 - y0) - dt * (beta * (y1 - y0) + dt * alpha * y1)
        out.append(y_hat)
        y0, y1 = y1, y_hat
    return torch.stack(out, -1)


def test_paper_scheme_one_step_is_exact():
    """Windows of 3 frames: the block predicts frame 2 from frames 0, 1 exactly as the official code."""
    torch.manual_seed(0)
    z = torch.randn(64, 3, 1, dtype=torch.float64)
    alpha, beta, dt = 3.7, 0.3, 0.2
    block = PhysicsBlock(parse("x'' = -alpha*x - beta*x'"), {"alpha": ParamSpec(init=alpha), "beta": ParamSpec(init=beta)},
                         integrator="symplectic", initial_state="backward", dtype=torch.float64)
    assert block.n_context == 2
    pred = block(z, 3, dt)
    y0, y1 = z[:, 0, 0], z[:, 1, 0]
    official = y1 + (y1 - y0) - dt * (beta * (y1 - y0) + dt * alpha * y1)
    torch.testing.assert_close(pred[:, 2, 0], official, rtol=1e-14, atol=1e-14)
    torch.testing.assert_close(pred[:, :2], z[:, :2], rtol=0, atol=0)


def test_paper_scheme_rollout_is_exact():
    torch.manual_seed(1)
    z = torch.randn(16, 2, 1, dtype=torch.float64)
    alpha, beta, dt = 4.0016, 0.08, 0.2
    block = PhysicsBlock(parse("x'' = -alpha*x - beta*x'"), {"alpha": ParamSpec(init=alpha), "beta": ParamSpec(init=beta)},
                         integrator="paper", initial_state="backward", dtype=torch.float64)
    pred = block(z, 50, dt)[..., 0]
    official = _official_damped(z[..., 0], alpha, beta, dt, 50)
    torch.testing.assert_close(pred, official, rtol=1e-11, atol=1e-11)


def test_paper_first_order_and_free_fall_updates():
    """Official first-order models: y - dt*alpha*y (explicit Euler); free fall: 2 y1 - y0 - alpha dt^2."""
    z = torch.tensor([[[0.7], [0.4]], [[-1.2], [3.0]]], dtype=torch.float64)
    dt = 0.1
    led = PhysicsBlock(parse("x' = -alpha*x"), {"alpha": ParamSpec(init=2.5)}, integrator="symplectic",
                       initial_state="backward", dtype=torch.float64)
    out = led(z[:, :1], 4, dt)[..., 0]
    expect = z[:, 0, 0, None] * (1 - dt * 2.5) ** torch.arange(4, dtype=torch.float64)
    torch.testing.assert_close(out, expect, rtol=1e-14, atol=1e-14)
    fall = PhysicsBlock(parse("y'' = -alpha"), {"alpha": ParamSpec(init=9.0)}, integrator="symplectic",
                        initial_state="backward", dtype=torch.float64)
    out = fall(z, 6, dt)[..., 0]
    y0, y1 = z[:, 0, 0], z[:, 1, 0]
    ref = [y0, y1]
    for _ in range(4):
        y0, y1 = y1, 2 * y1 - y0 - 9.0 * dt * dt
        ref.append(y1)
    torch.testing.assert_close(out, torch.stack(ref, -1), rtol=1e-13, atol=1e-13)


def test_substeps_split_the_interval():
    system = parse("x' = -k*x")
    one = simulate(system, {"k": 1.0}, {"x": 1.0}, 3, 0.2, "euler", substeps=4)
    # four Euler steps of 0.05 per frame
    np.testing.assert_allclose(one[:, 0].numpy(), [1.0, 0.95 ** 4, 0.95 ** 8], rtol=1e-14)


def test_simulate_batched_tensor_state_and_full():
    system = parse("x'' = -w2*x")
    y0 = torch.tensor([[[1.0, 0.0], [0.0, 1.0]], [[2.0, 0.0], [0.5, 0.5]]], dtype=torch.float64)  # (2, 2, 2)
    full = simulate(system, {"w2": 4.0}, y0, 30, 0.05, substeps=2, full=True)
    assert full.shape == (2, 2, 30, 2)
    t = torch.arange(30, dtype=torch.float64) * 0.05
    torch.testing.assert_close(full[0, 1, :, 0], torch.sin(2 * t) / 2, rtol=1e-6, atol=1e-7)
    values = simulate(system, {"w2": 4.0}, y0, 30, 0.05, substeps=2)
    assert values.shape == (2, 2, 30, 1)


@pytest.mark.parametrize("bad,match", [
    (dict(constants={}), "no value for w2"),
    (dict(constants={"w2": 1.0, "q": 2.0}), "q is not a constant"),
    (dict(y0={"x": [1.0]}), "needs 2 value"),
    (dict(y0={"z": [1.0, 0.0]}), "missing x"),
])
def test_simulate_rejects_bad_arguments(bad, match):
    kwargs = dict(constants={"w2": 1.0}, y0={"x": [1.0, 0.0]})
    kwargs.update(bad)
    with pytest.raises(ParameterError, match=match):
        simulate(parse("x'' = -w2*x"), kwargs["constants"], kwargs["y0"], 5, 0.1)


def test_simulate_uses_fixed_constants_and_overrides():
    system = parse("y'' = -g")
    a = simulate(system, {}, {"y": [0.0, 0.0]}, 2, 1.0)
    b = simulate(system, {"g": 1.0}, {"y": [0.0, 0.0]}, 2, 1.0)
    assert math.isclose(a[1, 0].item(), -G / 2, rel_tol=1e-14)
    assert math.isclose(b[1, 0].item(), -0.5, rel_tol=1e-14)


def test_constants_named_as_the_generated_codes_own_names_roll_out():
    # the NumPy field calls numpy.sin and fills `out`: a constant of either name was the module or the array
    from fitode.codegen.source import compile_numpy
    system = parse("x'' = -numpy*sin(x) - out*x'", free=["numpy", "out"])
    lay = StateLayout.from_system(system)
    traj = get_integrator("rk4")(lay).rollout(lambda y: compile_numpy(system)(y, 4.0, 0.5), np.array([[1.0, 0.0]]),
                                              20, 0.1)
    assert np.all(np.isfinite(traj)) and traj[0, 1, 0] < 1.0


@pytest.mark.parametrize("equation, affine", [
    ("x'' = -a", True), ("y'' = -w2*y - c*y'", True), ("I' = -gamma*(I - c)", True),
    ("x'' = -a; y'' = -g", True), ("x''' = -a*x' - b*x + c", True), ("x'' = -abs(a)*x'", True),
    ("x'' = -g/L*sin(x) - z*x'", False), ("x'' = -m*sign(x')", False), ("h' = -k*sqrt(h)", False),
    ("x'' = -a*x*x'", False), ("x'' = -k*abs(x')*x'", False)])
def test_an_affine_field_is_told_and_its_rollout_powered_up_is_the_stepped_one(equation, affine):
    from fitode.codegen.source import compile_numpy

    system = parse(equation)
    layout = StateLayout.from_system(system)
    assert layout.affine is affine
    if not affine:
        return
    fn = compile_numpy(system)
    rng = np.random.default_rng(3)
    consts = [rng.uniform(0.5, 2.0, 4) for _ in layout.constants]
    y0 = rng.normal(size=(4, layout.n_slots))
    for name in INTEGRATORS:
        integ = get_integrator(name)(layout)
        for frames, substeps in ((1, 1), (2, 1), (5, 3), (300, 1), (1025, 2)):
            stepped = integ.rollout(lambda y: fn(y, *consts), y0, frames, 0.01, substeps)
            powered = integ.rollout_affine(lambda y: fn(y, *consts), y0, frames, 0.01, substeps)
            assert powered.shape == stepped.shape
            np.testing.assert_allclose(powered, stepped, rtol=1e-11, atol=1e-11 * np.abs(stepped).max())
