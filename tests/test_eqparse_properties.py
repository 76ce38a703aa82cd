"""Property tests: any input gives an OdeSystem or an EquationError, never another exception.

Three generators: random strings over the language's alphabet, random edits of valid equations,
and random well-formed equations built from the grammar (these reach sympy and the solver).
derandomize=True makes every CI run see the same examples.
"""
import sympy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fitode.eqparse import EquationError, OdeSystem, analyse, parse

PIECES = list("xyzabgkLt'=+-*/^().0123456789e;\n #,") + [
    "sin(", "sqrt(", "exp(", "log(", "abs(", "sign(", "**", "d", "dx/dt", "d2x/dt2", "pi", "x''", "theta",
    "  ", "1e300", "foo(",
]
VALID = [
    "x'' = -g/L*sin(x) - z*x'",
    "z'' + g1*z' + g0*z = 0",
    "h' = -k*sqrt(h)",
    "u' = a*u - b*u*v\nv' = -c*v + d*u*v",
    "x'' = g*(sin(alpha) - mu*cos(alpha))",
    "dx/dt = -k*x; d2y/dt2 = -y + x",
    "x'' + delta*x' + alpha*x + beta*x^3 = 0",
    "exp(x'') = x; y' = -y^2.5e-3",
]

def fast(n: int) -> settings:
    return settings(max_examples=n, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def check(text: str) -> OdeSystem | None:
    try:
        system = parse(text)
    except EquationError as err:
        assert err.message and "\n" not in str(err)
        assert err.column is None or err.column >= 1
        return None
    assert isinstance(system, OdeSystem)
    assert len(system.states) >= 1 and set(system.orders) == set(system.states)
    for s in system.states:
        assert isinstance(system.rhs[s], sympy.Expr)
    return system


@fast(2500)
@given(st.lists(st.sampled_from(PIECES), max_size=40).map("".join))
def test_random_strings(text):
    check(text)


@st.composite
def mutated(draw):
    chars = list(draw(st.sampled_from(VALID)))
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.sampled_from(["insert", "delete", "replace"]))
        i = draw(st.integers(0, len(chars)))
        if op == "insert":
            chars.insert(i, draw(st.sampled_from(PIECES)))
        elif chars and i < len(chars):
            if op == "delete":
                del chars[i]
            else:
                chars[i] = draw(st.sampled_from(PIECES))
    return "".join(chars)


@fast(2000)
@given(mutated())
def test_mutated_equations(text):
    check(text)


NAMES = st.sampled_from(["x", "y", "a", "b", "g", "k", "pi", "e", "t", "sin", "foo"])
DERIVS = st.sampled_from(["x'", "x''", "y'", "y''", "x'''", "dx/dt", "d2y/dt2"])
NUMBERS = st.sampled_from(["0", "1", "2", ".5", "2.5e-3", "1e300", "9", "-1"])
FUNCS = st.sampled_from(["sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log",
                         "sqrt", "abs", "sign"])
EXPR = st.recursive(
    st.one_of(NAMES, DERIVS, NUMBERS),
    lambda inner: st.one_of(
        st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "^", "**"]), inner).map(" ".join),
        st.tuples(FUNCS, inner).map(lambda t: f"{t[0]}({t[1]})"),
        inner.map(lambda s: f"({s})"),
        inner.map(lambda s: f"-{s}"),
    ),
    max_leaves=10,
)
EQUATIONS = st.lists(st.tuples(st.one_of(DERIVS, EXPR), EXPR).map(" = ".join), min_size=1, max_size=3).map("; ".join)


@fast(800)
@given(EQUATIONS)
def test_grammar_generated_equations(text):
    check(text)


@fast(60)
@given(st.lists(st.tuples(DERIVS, EXPR).map(" = ".join), min_size=1, max_size=2).map("; ".join))
def test_analysis_never_crashes_on_parsed_systems(text):
    system = check(text)
    if system is not None:
        report = analyse(system)
        assert [c.name for c in report.constants] == list(system.learnable)
        assert all(c.scale in ("free", "dependent", "free-small-amplitude") for c in report.constants)
        assert all(isinstance(line, str) for line in report.lines())
