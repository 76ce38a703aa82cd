"""Generated source: readable, compiled once, numerically the equation, any batch shape; the CLI verb."""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy
import torch

from fitode.cli import main as cli_main
from fitode.codegen import (CodegenError, PhysicsBlock, StateLayout, compile_system, describe_init,
                            generate_source, init_scheme)
from fitode.eqparse import OdeSystem, deriv_symbol, parse

EQUATIONS = [
    "x'' = -g0*x - g1*x'",
    "theta'' = -g/L*sin(theta) - zeta*theta'",
    "h' = -k*sqrt(h)",
    "u' = a*u - b*u*v; v' = -c*v + d*u*v",
    "x'' = -k*x^3 + exp(-x'^2)*abs(x) - sign(x')*mu + log(1 + x^2)/tanh(1 + x'^2)",
    "x''' = -a*x'' - b*x' - sinh(x)/cosh(x); y' = atan(x)*y - sqrt(2)*y + pi*e - asin(0.5*tanh(y))",
    "r'' = 2^x*0; x' = -x",
]


def _numeric_rhs(system: OdeSystem, layout: StateLayout, y: np.ndarray, consts: dict[str, float]) -> np.ndarray:
    """The layout's derivative vector evaluated by sympy's own numpy printer (an independent path)."""
    syms = [s.symbol for s in layout.slots] + [sympy.Symbol(n) for n in layout.constants]
    f = sympy.lambdify(syms, list(layout.derivatives), modules="numpy")
    cvals = [consts.get(n, system.fixed.get(n)) for n in layout.constants]
    out = f(*[y[..., i] for i in range(layout.n_slots)], *cvals)
    return np.stack([np.broadcast_to(np.asarray(o, dtype=float), y.shape[:-1]) for o in out], -1)


@pytest.mark.parametrize("text", EQUATIONS)
def test_generated_field_matches_sympy_on_any_batch_shape(text):
    system = parse(text)
    vf = compile_system(system)
    rng = np.random.default_rng(0)
    y = rng.uniform(0.2, 0.9, size=(2, 3, vf.layout.n_slots))
    consts = {n: float(v) for n, v in zip(system.learnable, rng.uniform(0.5, 2.0, len(system.learnable)))}
    args = [torch.tensor(consts.get(n, system.fixed.get(n)), dtype=torch.float64) for n in vf.layout.constants]
    got = vf(torch.tensor(y), *args)
    assert got.shape == y.shape
    np.testing.assert_allclose(got.numpy(), _numeric_rhs(system, vf.layout, y, consts), rtol=1e-12, atol=1e-12)
    # a single state (no batch) works too
    assert vf(torch.tensor(y[0, 0]), *args).shape == (vf.layout.n_slots,)


def test_source_is_readable_and_is_what_runs():
    system = parse("theta'' = -g/L*sin(theta) - zeta*theta'")
    src = compile_system(system).source
    assert "def vector_field(state, L, zeta, g):" in src
    assert "theta, theta_t = state.unbind(-1)" in src
    assert "theta_tt = -theta_t*zeta - g*torch.sin(theta)/L  # theta''" in src
    assert "return torch.stack((theta_t, theta_tt), -1)" in src
    assert "# Fixed constants: g = 9.80665" in src
    # the printed source, executed on its own, is the same function
    ns: dict = {}
    exec(src, ns)
    y = torch.tensor([[0.3, -0.1], [1.2, 0.4]], dtype=torch.float64)
    c = [torch.tensor(v, dtype=torch.float64) for v in (1.5, 0.1, 9.80665)]
    torch.testing.assert_close(ns["vector_field"](y, *c), compile_system(system)(y, *c))
    assert PhysicsBlock(system).source.endswith(src)


def test_compiled_once_per_normalised_equation():
    a = compile_system(parse("x'' = -g0*x - g1*x'"))
    b = compile_system(parse("x'' + g0*x + g1*x' = 0"))
    c = compile_system(parse("x''   =   -(g0*x + g1*x')"))
    assert a is b is c
    # constants in another order make another signature: vector_field(state, g1, g0)
    assert compile_system(parse("x'' + g1*x' + g0*x = 0")) is not a
    assert compile_system(parse("x'' = -g0*x - 2*g1*x'")) is not a


def test_numbers_fold_to_floats():
    src = compile_system(parse("y' = -sqrt(2)*y + log(3) + pi + e")).source
    assert "torch.sqrt(2)" not in src and "torch.log(3)" not in src
    assert "1.41421356237309" in src and "1.09861228866810" in src


def test_state_free_rhs_keeps_the_batch_shape():
    vf = compile_system(parse("y'' = -g"))
    out = vf(torch.zeros(4, 7, 2), torch.tensor(9.80665))
    assert out.shape == (4, 7, 2)
    assert torch.all(out[..., 1] == -9.80665)


def test_awkward_names_become_identifiers():
    s, k, t = sympy.Symbol("torch"), sympy.Symbol("lambda"), sympy.Symbol("state")
    x, xt = deriv_symbol("x", 0), deriv_symbol("x", 1)
    system = OdeSystem(states=("x",), orders={"x": 2}, rhs={"x": -s * x - k * xt + t},
                       learnable=("torch", "lambda", "state"))
    vf = compile_system(system)
    assert "def vector_field(state, torch_, lambda_, state_):" in vf.source
    out = vf(torch.tensor([1.0, 2.0]), torch.tensor(3.0), torch.tensor(0.5), torch.tensor(0.25))
    torch.testing.assert_close(out, torch.tensor([2.0, -3.0 - 1.0 + 0.25]))


def test_unsupported_function_and_unknown_name_are_refused():
    x = deriv_symbol("x", 0)
    for fn in (sympy.erfc, sympy.gamma):  # erfc: no printer; gamma: printed as a missing torch function
        with pytest.raises(CodegenError, match="erfc|gamma"):
            compile_system(OdeSystem(states=("x",), orders={"x": 1}, rhs={"x": fn(x)}))
    stray = OdeSystem(states=("x",), orders={"x": 1}, rhs={"x": sympy.Symbol("q") * x})
    with pytest.raises(CodegenError, match="q is neither"):
        compile_system(stray)


def test_layout_of_mixed_orders():
    lay = StateLayout.from_system(parse("x'' = -x + q; q' = -q; w''' = -w"))
    assert [s.label for s in lay.slots] == ["x", "x'", "q", "w", "w'", "w''"]
    assert lay.value_slots == (0, 2, 3) and lay.top_slots == (1, 2, 5) and lay.derivative_slots == (1, 4, 5)
    assert lay.derivatives[0] == deriv_symbol("x", 1) and lay.derivatives[4] == deriv_symbol("w", 2)


def test_finite_difference_schemes():
    central = init_scheme(2, "difference", 3)
    assert central.anchor == 1 and central.weights[1] == (-0.5, 0.0, 0.5) and central.error_order[1] == 2
    five = init_scheme(2)
    assert five.context == 5 and five.anchor == 2 and five.error_order[1] == 4
    np.testing.assert_allclose(five.weights[1], [1 / 12, -2 / 3, 0, 2 / 3, -1 / 12])
    paper = init_scheme(2, "backward")
    assert paper.context == 2 and paper.anchor == 1 and paper.weights[1] == (-1.0, 1.0)
    # weights differentiate polynomials exactly up to their order
    for scheme in (central, five, init_scheme(4), init_scheme(3, "backward", 5)):
        offsets = np.arange(scheme.context) - scheme.anchor
        for k, w in enumerate(scheme.weights):
            for p in range(scheme.context):
                expect = math.factorial(p) if p == k else 0.0
                assert abs(np.dot(w, offsets.astype(float) ** p) - expect) < 1e-9
    text = describe_init(StateLayout.from_system(parse("x'' = -x")), "difference", 3)
    assert "z' = (-z[0] + z[2])/(2*dt)" in text and "O(dt^2)" in text


def test_generate_source_describes_the_step():
    text = generate_source(parse("x'' = -k*x"), integrator="paper", substeps=4, initial_state="backward")
    assert "# Integrator: symplectic" in text and "h = dt/4" in text and "2 x_t - x_{t-1}" in text
    assert "z' = (-z[0] + z[1])/dt" in text


def test_cli_prints_source(capsys):
    assert cli_main(["codegen", "--eq", "x'' = -k*x - c*x'", "--integrator", "rk4", "--substeps", "2"]) == 0
    out = capsys.readouterr().out
    assert "def vector_field(state, k, c):" in out and "x_tt = -c*x_t - k*x  # x''" in out
    ns: dict = {}
    exec(out, ns)  # what it prints is valid Python
    assert callable(ns["vector_field"])


@pytest.mark.parametrize("argv,msg", [
    (["codegen", "--eq", "x'' = -k*"], "column"),
    (["codegen", "--eq", "x' = -k*x", "--const", "k=zz"], "NAME=VALUE"),
    (["codegen", "--eq", "x'' = -k*x", "--context", "1"], "context"),
    (["codegen"], "required"),
])
def test_cli_errors_are_one_line(argv, msg, capsys):
    assert cli_main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and msg in err and "Traceback" not in err


def _shipped() -> list[str]:
    try:
        from fitode import eqfile
    except ImportError:  # equation files not in this checkout yet
        return []
    return [n if isinstance(n, str) else n.name for n in eqfile.list_systems()]


@pytest.mark.parametrize("name", _shipped() or [pytest.param(None, marks=pytest.mark.skip("no equation files yet"))])
def test_every_shipped_equation_compiles_and_runs(name):
    from fitode.eqfile import resolve

    system, spec = resolve(eq=None, eq_file=None, system=name, const={}, free=())
    params = dict(spec.parameters) if spec is not None else {}
    for init in ("difference", "backward"):
        block = PhysicsBlock(system, params, initial_state=init, dtype=torch.float64)
        torch.manual_seed(0)
        z = 0.5 + 0.1 * torch.rand(4, block.n_context, block.dim, dtype=torch.float64)
        out = block(z, 12, 0.05)
        assert out.shape == (4, 12, block.dim) and torch.isfinite(out).all()
        out.sum().backward()
        assert all(p.grad is not None for p in block.parameters())
    assert "def vector_field" in generate_source(system)
