"""PhysicsBlock: shapes, initial states, constants and bounds, gradients, learnable init, NaN guard."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from torch.func import functional_call

from fitode.codegen import NonFiniteError, ParameterError, PhysicsBlock, simulate
from fitode.errors import FitodeError
from fitode.eqparse import ParamSpec, parse

OMEGA, ZETA = 2.0, 0.04
G0, G1 = OMEGA ** 2 + ZETA ** 2, 2 * ZETA
DAMPED = "x'' = -g0*x - g1*x'"


def _damped_windows(n_windows: int = 8, window: int = 20, dt: float = 0.2) -> torch.Tensor:
    t = torch.arange(n_windows * 3 + window, dtype=torch.float64) * dt
    z = torch.exp(-ZETA * t) * torch.cos(OMEGA * t)
    starts = torch.arange(n_windows) * 3
    return z[starts[:, None] + torch.arange(window)][..., None]


def _block(eq=DAMPED, params=None, **kw):
    params = params if params is not None else {"g0": ParamSpec(init=G0), "g1": ParamSpec(init=G1)}
    kw.setdefault("dtype", torch.float64)
    return PhysicsBlock(parse(eq), params, **kw)


# --------------------------------------------------------------------------- shapes and frames
def test_dim_context_and_shapes():
    block = _block()
    assert block.dim == 1 and block.n_context == 5 and block.anchor == 2
    z = _damped_windows()
    out = block(z, 20, 0.2)
    assert out.shape == (8, 20, 1)
    # any leading shape; extra frames in z_head are ignored
    out2 = block(z.reshape(2, 4, 20, 1), 20, 0.2)
    torch.testing.assert_close(out2.reshape(8, 20, 1), out)
    # frames up to the anchor are the inputs themselves
    torch.testing.assert_close(out[:, :3], z[:, :3], rtol=0, atol=0)


def test_rollout_from_exact_frames_follows_the_trajectory():
    z = _damped_windows()
    errors = []
    for init, context in (("difference", 5), ("difference", 3), ("backward", 2)):
        block = _block(initial_state=init, context=context, substeps=4)
        out = block(z[:, :block.n_context], 20, 0.2)
        errors.append((out - z).abs().max().item())
    # velocity errors dt^4/30 z^(5), dt^2/6 z^(3), dt/2 z^(2) at omega*dt = 0.4
    assert errors[0] < 2e-3 and errors[0] < errors[1] / 10 < errors[2] / 20, errors


def test_multi_state_system_shapes_and_values():
    system = parse("u' = a*u - b*u*v; v' = -c*v + d*u*v")
    consts = {"a": 1.1, "b": 0.4, "c": 0.4, "d": 0.1}
    block = PhysicsBlock(system, {k: ParamSpec(init=v) for k, v in consts.items()}, dtype=torch.float64)
    assert block.dim == 2 and block.n_context == 1
    ref = simulate(system, consts, {"u": 10.0, "v": 5.0}, 30, 0.1)
    out = block(ref[None, :1], 30, 0.1)[0]
    torch.testing.assert_close(out, ref, rtol=1e-13, atol=1e-13)


def test_mixed_orders_initial_state():
    # second-order x and first-order q: the state holds x, x', q
    block = PhysicsBlock(parse("x'' = -k*x + q; q' = -q"), dtype=torch.float64, initial_state="difference", context=3)
    t = torch.arange(3, dtype=torch.float64) * 0.1
    z = torch.stack([t ** 2, torch.exp(-t)], -1)[None]  # (1, 3, 2)
    y0 = block.initial_state(z, 0.1)
    torch.testing.assert_close(y0[0], torch.tensor([0.01, 0.2, math.exp(-0.1)], dtype=torch.float64))


def test_bad_inputs_raise():
    block = _block()
    with pytest.raises(ValueError, match="needs 5"):
        block(torch.zeros(3, 2, 1), 10, 0.1)
    with pytest.raises(ValueError, match="shape"):
        block(torch.zeros(3, 5, 2), 10, 0.1)
    with pytest.raises(ParameterError, match="substeps"):
        _block(substeps=0)
    with pytest.raises(ParameterError, match="unknown init"):
        _block(initial_state="spline")
    with pytest.raises(ParameterError, match="context"):
        _block(context=1)


# --------------------------------------------------------------------------- constants
def test_default_inits_and_lr_scales():
    block = PhysicsBlock(parse("x'' = -a*x - b*x' + c + d + p + f"),
                         {"a": ParamSpec(init=0.05), "b": ParamSpec(init=-37.0), "c": ParamSpec(min=0.0),
                          "d": ParamSpec(min=2.0, max=4.0), "p": ParamSpec(max=-3.0), "f": ParamSpec(init=0.0)})
    values = {k: v.item() for k, v in block.constants().items()}
    assert values == pytest.approx({"a": 0.05, "b": -37.0, "c": 1.0, "d": 3.0, "p": -6.0, "f": 0.0})
    assert block.lr_scale("a") == pytest.approx(0.01)  # 10**floor(log10 0.05)
    assert block.lr_scale("b") == 10.0
    assert block.lr_scale("f") == 1.0
    assert [block.parametrisation(n) for n in "cdp"] == ["log-lower", "sigmoid", "log-upper"]
    assert all(block.lr_scale(n) == 1.0 for n in "cdp")
    groups = block.param_groups(lr=0.1)
    assert [g["name"] for g in groups] == list("abcdpf")
    assert groups[1]["lr"] == pytest.approx(1.0)
    assert all(len(g["params"]) == 1 and g["params"][0].requires_grad for g in groups)
    block.set_constants({"b": 4.0})
    assert block.lr_scale("b") == 1.0 and block.constants()["b"].item() == pytest.approx(4.0)


def test_lr_scale_follows_a_growing_value_and_never_shrinks():
    from fitode.train.optim import BatchedAdam
    block = PhysicsBlock(parse("x'' = -a*x - b*x'"), {"b": ParamSpec(min=0.0)}, restarts=3)
    block.set_constants({"a": [0.5, 0.5, -0.3]})
    u = block.param_groups()[0]["params"][0]
    opt = BatchedAdam([{"params": [u], "lr": 0.05, "name": "a"}], 3)
    assert block.follow_scales() == {}  # still inside the starts' decade
    block.set_constants({"a": [0.5, 0.5, -0.3]})
    with torch.no_grad():
        u.copy_(torch.tensor([42.0, 0.5, -0.3]))  # restart 0 climbed to 4.2 (raw u is value/0.1)
    before = block.constants()["a"].clone()
    (block.constants()["a"] ** 2).sum().backward()
    opt.step(torch.ones(3, dtype=torch.bool))
    moved = (block.constants()["a"] - before).detach().abs()
    assert moved.tolist() == pytest.approx([0.005, 0.005, 0.005], rel=1e-4)  # lr 0.05 x scale 0.1 each
    now = block.constants()["a"].detach().clone()
    grown = block.follow_scales()
    assert grown["a"].tolist() == [10.0, 1.0, 1.0]  # only the restart that passed 1 grows, to scale 1
    torch.testing.assert_close(block.constants()["a"].detach(), now)  # the values do not move
    opt.rescaled(u, grown["a"])
    opt.zero_grad()
    (block.constants()["a"] ** 2).sum().backward()
    opt.step(torch.ones(3, dtype=torch.bool))
    moved = (block.constants()["a"] - now).detach().abs()
    # Adam's second step is near lr (the gradient changed a little): ten times the old pace
    assert moved[0].item() == pytest.approx(0.05, rel=2e-2)
    assert moved[1:].tolist() == pytest.approx([0.005, 0.005], rel=2e-2)
    with torch.no_grad():
        u[0] = 0.001  # the value falls back near zero: the scale stays where it grew to
    assert block.follow_scales() == {}


def test_bounds_hold_under_any_optimiser_step():
    block = _block("x'' = -k/m*x", {"k": ParamSpec(init=2.0, min=0.0), "m": ParamSpec(init=1.0, min=0.5, max=2.0)})
    opt = torch.optim.Adam(block.param_groups(lr=0.5))
    z = _damped_windows()
    for _ in range(40):
        opt.zero_grad()
        c = block.constants()
        # pushes k below 0 and m above 2: the parametrisation must stop both short of the bound
        loss = (block(z[:, :5], 20, 0.2) - z).pow(2).mean() + c["k"] - c["m"]
        loss.backward()
        assert all(p.grad is not None and torch.isfinite(p.grad) for p in block.parameters())
        opt.step()
        c = block.constants()
        assert c["k"].item() > 0 and 0.5 < c["m"].item() < 2.0


def test_set_constants_respects_bounds():
    block = _block("x'' = -k*x", {"k": ParamSpec(min=0.0)})
    with pytest.raises(ParameterError, match="outside its bounds"):
        block.set_constants({"k": -1.0})
    block.set_constants({"k": -1.0}, clip=True)
    assert 0 < block.constants()["k"].item() < 1e-5
    with pytest.raises(ParameterError, match="not a learnable constant"):
        block.set_constants({"g": 1.0})
    with pytest.raises(ParameterError, match="strictly inside"):
        _block("x'' = -k*x", {"k": ParamSpec(init=0.0, min=0.0)})
    assert isinstance(ParameterError("x"), FitodeError)


def test_fixed_constants_are_buffers():
    block = PhysicsBlock(parse("theta'' = -g/L*sin(theta)"), {"L": ParamSpec(init=1.0, min=0.0)})
    assert block.fixed_constants() == pytest.approx({"g": 9.80665})
    assert "fixed_values" in dict(block.named_buffers())
    assert [n for n, _ in block.named_parameters()] == ["const_L"]


# --------------------------------------------------------------------------- gradients
@pytest.mark.parametrize("eq,params,init", [
    (DAMPED, {"g0": ParamSpec(init=G0), "g1": ParamSpec(init=G1)}, "difference"),
    ("theta'' = -g/L*sin(theta) - zeta*theta'", {"L": ParamSpec(init=1.5, min=0.0), "zeta": ParamSpec(init=0.1)},
     "backward"),
    ("h' = -k*sqrt(h)", {"k": ParamSpec(init=0.3, min=0.0, max=2.0)}, "difference"),
    ("u' = a*u - b*u*v; v' = -c*v + d*u*v", {n: ParamSpec(init=v) for n, v in zip("abcd", (1.1, 0.4, 0.4, 0.1))},
     "difference"),
])
@pytest.mark.parametrize("integrator", ["rk4", "symplectic"])
def test_gradcheck_every_constant(eq, params, init, integrator):
    block = PhysicsBlock(parse(eq), params, integrator=integrator, substeps=2, initial_state=init, dtype=torch.float64)
    torch.manual_seed(0)
    z = 0.5 + 0.3 * torch.rand(3, block.n_context, block.dim, dtype=torch.float64)
    names = [n for n, _ in block.named_parameters()]
    raw = tuple(p.detach().clone().requires_grad_(True) for _, p in block.named_parameters())

    def f(*args):
        *ps, zz = args
        return functional_call(block, dict(zip(names, ps)), (zz, 8, 0.1))

    assert torch.autograd.gradcheck(f, raw + (z.requires_grad_(True),), eps=1e-6, atol=1e-7, rtol=1e-5)


# --------------------------------------------------------------------------- learnable initial state
def test_learnable_init_seeds_from_differences_then_learns():
    z = _damped_windows()
    block = _block(initial_state="learnable", n_windows=10)
    assert block.n_context == 3
    idx = torch.tensor([0, 3, 5, 7, 1, 2, 4, 6])
    out = block(z[:, :3], 20, 0.2, window_index=idx)
    seeded = block.initial_derivatives.detach()[idx, 0]
    torch.testing.assert_close(seeded, (z[:, 2, 0] - z[:, 0, 0]) / 0.4)
    assert block.initialised[idx].all() and not block.initialised[[8, 9]].any()
    # a second call does not reseed, even from other frames
    block(torch.zeros_like(z[:, :3]), 20, 0.2, window_index=idx)
    torch.testing.assert_close(block.initial_derivatives.detach()[idx, 0], seeded)
    # gradients reach the per-window values; the group is exposed to the optimiser
    out.pow(2).sum().backward()
    assert block.initial_derivatives.grad[idx].abs().min() > 0
    assert block.initial_derivatives.grad[[8, 9]].abs().max() == 0
    names = [g["name"] for g in block.param_groups(0.01)]
    assert names == ["g0", "g1", "initial_derivatives"]


def test_learnable_init_removes_the_velocity_bias():
    """With the true velocities set through init_from-like assignment, the rollout is the exact solution."""
    z = _damped_windows()
    block = _block(initial_state="learnable", n_windows=8, substeps=4)
    idx = torch.arange(8)
    block.init_from(z[:, :3], idx, 0.2)
    t1 = (idx * 3 + 1).double() * 0.2
    true_v = torch.exp(-ZETA * t1) * (-ZETA * torch.cos(OMEGA * t1) - OMEGA * torch.sin(OMEGA * t1))
    with torch.no_grad():
        block.initial_derivatives[:, 0] = true_v
    out = block(z[:, :3], 20, 0.2, window_index=idx)
    assert (out - z).abs().max().item() < 2e-5  # RK4 at h = 0.05: measured 5e-6
    # without window_index the block falls back to the differences
    diff = _block(initial_state="difference", context=3, substeps=4)
    torch.testing.assert_close(block(z[:, :3], 20, 0.2), diff(z[:, :3], 20, 0.2))


def test_learnable_init_needs_n_windows():
    with pytest.raises(ParameterError, match="n_windows"):
        _block(initial_state="learnable")


# --------------------------------------------------------------------------- the non-finite guard
def test_division_by_zero_is_named():
    block = PhysicsBlock(parse("x' = -k; y' = 1/x"), {"k": ParamSpec(init=1.0)}, dtype=torch.float64)
    z = torch.tensor([[[1.0, 0.0]], [[3.0, 0.0]]], dtype=torch.float64)
    with pytest.raises(NonFiniteError) as info:
        block(z, 8, 0.25)
    err = info.value
    assert err.term == "1/x" and err.frame == 4 and err.window == 0 and err.values == {"x": 0.0}
    assert "1/x = inf" in str(err) and "\n" not in str(err)


def test_sqrt_of_negative_is_named():
    block = PhysicsBlock(parse("h' = -k*sqrt(h)"), {"k": ParamSpec(init=1.0, min=0.0)}, dtype=torch.float64)
    with pytest.raises(NonFiniteError, match=r"sqrt\(h\) = nan in the step to frame 2") as info:
        block(torch.tensor([[[0.5]], [[0.01]]], dtype=torch.float64), 10, 0.1)
    assert info.value.window == 1 and info.value.values["h"] < 0


def test_overflow_is_named():
    block = PhysicsBlock(parse("x' = x^2"), dtype=torch.float32)
    with pytest.raises(NonFiniteError, match=r"x\*\*2 = inf") as info:
        block(torch.ones(1, 1, 1), 30, 0.1)
    assert info.value.frame == 12 and info.value.values["x"] > 1e19


def test_nan_constant_and_nan_frames_are_named():
    block = _block()
    z = _damped_windows()[:, :5]
    with torch.no_grad():
        block.const_g1.fill_(float("nan"))
    with pytest.raises(NonFiniteError, match="constant g1 is nan"):
        block(z, 20, 0.2)
    block = _block()
    z = z.clone()
    z[2, 4, 0] = float("nan")
    with pytest.raises(NonFiniteError, match="encoded frames"):
        block(z, 20, 0.2)


def test_check_finite_can_be_switched_off():
    block = PhysicsBlock(parse("h' = -k*sqrt(h)"), {"k": ParamSpec(init=1.0, min=0.0)}, dtype=torch.float64,
                         check_finite=False)
    out = block(torch.tensor([[[0.01]]], dtype=torch.float64), 10, 0.1)
    assert torch.isnan(out).any()


def test_simulate_guards_too():
    with pytest.raises(NonFiniteError, match="exp"):
        simulate(parse("x' = exp(x)"), {}, {"x": 1.0}, 30, 0.1, dtype=torch.float32)


@pytest.mark.parametrize("eq, constants, y0", [
    ("theta'' = -g/L*sin(theta) - zeta*theta'", {"L": 0.9, "zeta": 0.05}, {"theta": [0.8, 0.0]}),
    ("y'' = -g", {}, {"y": [1.0, 2.0]}),
    ("u' = a*u - b*u*v; v' = -c*v + d*u*v", {"a": 1.0, "b": 0.5, "c": 0.8, "d": 0.3}, {"u": 2.0, "v": 1.0}),
])
def test_simulate_in_numpy_takes_the_same_steps(eq, constants, y0):
    system = parse(eq)
    ref = simulate(system, constants, y0, 60, 0.05, substeps=7, full=True).numpy()
    got = simulate(system, constants, y0, 60, 0.05, substeps=7, full=True, numpy=True)
    assert isinstance(got, np.ndarray) and got.shape == ref.shape
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)


def test_simulate_in_numpy_names_what_went_non_finite():
    with pytest.raises(NonFiniteError, match="exp"):
        simulate(parse("x' = exp(x)"), {}, {"x": 1.0}, 30, 0.1, numpy=True)


# --------------------------------------------------------------------------- devices and dtypes
def test_float32_block_follows_input_dtype():
    block = _block(dtype=torch.float32)
    z = _damped_windows().float()
    out = block(z[:, :5], 20, 0.2)
    assert out.dtype == torch.float32
    ref = _block()(z.double()[:, :5], 20, 0.2)
    assert (out.double() - ref).abs().max().item() < 1e-5


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_matches_cpu():
    z = _damped_windows()
    for init in ("difference", "learnable"):
        cpu = _block(initial_state=init, n_windows=8, substeps=2)
        gpu = _block(initial_state=init, n_windows=8, substeps=2).cuda()
        idx = torch.arange(8)
        a = cpu(z[:, :5], 20, 0.2, window_index=idx)
        b = gpu(z[:, :5].cuda(), 20, 0.2, window_index=idx.cuda())
        assert b.device.type == "cuda"
        torch.testing.assert_close(b.cpu(), a)
        b.sum().backward()
        assert gpu.const_g0.grad.device.type == "cuda"


def test_block_pickles_and_copies():
    import copy
    import pickle

    block = _block(initial_state="learnable", n_windows=8)
    block.set_constants({"g0": 3.0})
    z = _damped_windows()[:, :3]
    idx = torch.arange(8)
    out = block(z, 20, 0.2, window_index=idx)
    for clone in (pickle.loads(pickle.dumps(block)), copy.deepcopy(block)):
        torch.testing.assert_close(clone(z, 20, 0.2, window_index=idx), out)
        assert clone.constants()["g0"].item() == 3.0


def test_a_rollout_of_some_restarts_is_those_restarts_rows_of_the_whole():
    # the training loop rolls out only the restarts still training: it must be the same numbers
    block = PhysicsBlock(parse("x'' = -a*x - b*x'"), {"b": ParamSpec(min=0.0)}, restarts=4)
    block.set_constants({"a": [1.0, 2.0, 3.0, 4.0], "b": [0.1, 0.2, 0.3, 0.4]})
    head = torch.randn(4, 5, block.n_context, 1)
    whole = block(head, 12, 0.1)
    some = torch.tensor([1, 3])
    part = block(head[some], 12, 0.1, restarts=some)
    torch.testing.assert_close(part, whole[some], rtol=0, atol=0)
    (part ** 2).sum().backward()
    grad = block.param_groups()[0]["params"][0].grad
    assert grad[0] == 0 and grad[2] == 0 and grad[1] != 0 and grad[3] != 0  # the others are untouched
    with pytest.raises(ValueError):
        block(head, 12, 0.1, restarts=some)  # z_head of every restart for two of them
