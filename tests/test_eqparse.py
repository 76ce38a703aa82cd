"""The equation language: what parse accepts, what it builds, and every refusal with its column."""
import pytest
import sympy

from fitode.eqparse import EquationError, MAX_LENGTH, OdeSystem, deriv_symbol, parse

S = sympy.Symbol


def d(name, k):
    return deriv_symbol(name, k)


def same(a, b) -> bool:
    return sympy.simplify(a - b) == 0


# --- accepted forms ----------------------------------------------------------------------------


def test_pendulum_explicit():
    s = parse("x'' = -g/L*sin(x) - z*x'")
    assert isinstance(s, OdeSystem)
    assert s.states == ("x",)
    assert s.orders == {"x": 2}
    assert same(s.rhs["x"], -S("g") / S("L") * sympy.sin(S("x")) - S("z") * d("x", 1))
    assert s.fixed == {"g": 9.80665}
    assert s.learnable == ("L", "z")
    assert s.text == "x'' = -g/L*sin(x) - z*x'"


@pytest.mark.parametrize("text", [
    "x'' = -k*x", "d2x/dt2 = -k*x", "d^2x/dt^2 = -k*x", "x'' + k*x = 0", "0 = x'' + k*x",
    "  x ' '=-k * x  ", "x''=-(k)*x", "x''=-k*x;", "\n\nx''=-k*x\n\n", "x'' = -k*x  # Hooke",
])
def test_equivalent_spellings(text):
    s = parse(text)
    assert s.states == ("x",) and s.orders == {"x": 2}
    assert same(s.rhs["x"], -S("k") * S("x"))
    assert s.learnable == ("k",)


def test_first_order_dx_dt():
    s = parse("dx/dt = -k*x")
    assert s.orders == {"x": 1}
    assert same(s.rhs["x"], -S("k") * S("x"))


def test_prime_of_any_order():
    s = parse("x'''' = -x''' - x'' - x' - x")
    assert s.orders == {"x": 4}
    assert same(s.rhs["x"], -d("x", 3) - d("x", 2) - d("x", 1) - S("x"))


def test_implicit_damped_oscillator():
    s = parse("z'' + g1*z' + g0*z = 0")
    assert same(s.rhs["z"], -S("g1") * d("z", 1) - S("g0") * S("z"))
    assert s.learnable == ("g1", "g0")  # order of first appearance


def test_implicit_with_coefficient_on_the_highest_derivative():
    s = parse("m*x'' + c*x' + k*x = 0")
    assert same(s.rhs["x"], -(S("c") * d("x", 1) + S("k") * S("x")) / S("m"))
    assert s.learnable == ("m", "c", "k")


@pytest.mark.parametrize("text, expected", [
    ("exp(x'') = x", sympy.log(S("x"))),
    ("sqrt(x') = x", S("x") ** 2),
    ("k/x' = x", S("k") / S("x")),
    ("log(x' + 1)*k = x", sympy.exp(S("x") / S("k")) - 1),
    ("atan(x') = x", sympy.tan(S("x"))),
    ("x'/(x' + 1) = x", S("x") / (1 - S("x"))),
])
def test_implicit_forms_with_one_solution(text, expected):
    s = parse(text)
    assert same(s.rhs["x"], expected)


def test_system_separated_by_semicolons_and_newlines():
    for text in ("u' = a*u - b*u*v; v' = -c*v + d*u*v", "u' = a*u - b*u*v\nv' = -c*v + d*u*v",
                 "u' = a*u - b*u*v;\n\n v' = -c*v + d*u*v;"):
        s = parse(text)
        assert s.states == ("u", "v")
        assert s.orders == {"u": 1, "v": 1}
        assert s.learnable == ("a", "b", "c", "d")
        assert same(s.rhs["v"], -S("c") * S("v") + S("d") * S("u") * S("v"))


def test_states_follow_equation_order_not_first_mention():
    s = parse("y' = x; x' = -y")
    assert s.states == ("y", "x")


def test_mixed_orders_and_coupling():
    s = parse("x'' = -k*(x - y); y' = -y + x'")
    assert s.orders == {"x": 2, "y": 1}
    assert same(s.rhs["y"], -S("y") + d("x", 1))


@pytest.mark.parametrize("text, value", [
    ("x' = 1", 1), ("x' = .5", 0.5), ("x' = 2.5e-3", 2.5e-3), ("x' = 1.", 1.0), ("x' = 1E2", 100.0),
    ("x' = 2^3", 8), ("x' = 2**3", 8), ("x' = 2^3^2", 512), ("x' = -2^2", -4), ("x' = 2^-1", 0.5),
    ("x' = 7 - 2 - 1", 4), ("x' = 8/2/2", 2), ("x' = --3", 3), ("x' = +3", 3), ("x' = 2*(1 + 2)", 6),
])
def test_numbers_and_operator_precedence(text, value):
    assert float(parse(text).rhs["x"]) == pytest.approx(value)


def test_functions_and_math_constants():
    s = parse("x' = sin(x) + cos(x) + tan(x) + asin(x) + acos(x) + atan(x) + sinh(x) + cosh(x) + tanh(x)"
              " + exp(x) + log(x) + sqrt(x) + abs(x) + sign(x) + pi + e")
    x = S("x")
    expected = (sympy.sin(x) + sympy.cos(x) + sympy.tan(x) + sympy.asin(x) + sympy.acos(x) + sympy.atan(x)
                + sympy.sinh(x) + sympy.cosh(x) + sympy.tanh(x) + sympy.exp(x) + sympy.log(x) + sympy.sqrt(x)
                + sympy.Abs(x) + sympy.sign(x) + sympy.pi + sympy.E)
    assert same(s.rhs["x"], expected)
    assert s.learnable == () and s.fixed == {}  # pi and e are exact constants, not names


def test_e_power_is_exp():
    assert same(parse("x' = e^(-k*x)").rhs["x"], sympy.exp(-S("k") * S("x")))


def test_a_known_constant_can_be_fixed_to_another_value_or_freed():
    assert parse("x'' = -g", fix={"g": 9.81}).fixed == {"g": 9.81}
    s = parse("x'' = -g/L*sin(x)", free=["g"])
    assert s.fixed == {} and s.learnable == ("g", "L")


def test_a_learnable_constant_can_be_fixed():
    s = parse("x'' = -g/L*sin(x) - z*x'", fix={"L": 2.0})
    assert s.fixed == {"g": 9.80665, "L": 2.0}
    assert s.learnable == ("z",)


def test_freeing_a_learnable_constant_is_harmless():
    assert parse("x' = -k*x", free=["k"]).learnable == ("k",)


def test_a_state_may_reuse_the_name_of_a_known_constant():
    s = parse("g' = -k*g")
    assert s.states == ("g",) and s.fixed == {} and s.learnable == ("k",)


def test_normal_form_reads_like_the_input():
    assert parse("x'' = g*(sin(a) - mu*cos(a))").normal_form() == ["x'' = g*(sin(a) - mu*cos(a))"]
    assert parse("z'' + c*z' + k*z = 0").normal_form() == ["z'' = -c*z' - k*z"]


def test_input_at_the_length_limit_is_accepted():
    head = "x' = -k*x"
    text = head + " " * (MAX_LENGTH - len(head))
    assert len(text) == MAX_LENGTH
    assert parse(text).learnable == ("k",)


# --- refusals: message and column ---------------------------------------------------------------


def refusal(text, **kw) -> EquationError:
    with pytest.raises(EquationError) as info:
        parse(text, **kw)
    return info.value


@pytest.mark.parametrize("text, column, words", [
    ("x'' = 2x", 8, "explicit '*'"),
    ("x'' = (x", 9, "expected ')'"),
    ("x'' = x +", 10, "end of the text"),
    ("x'' == x", 6, "unexpected '='"),
    ("x' = 1 = 2", 8, "unexpected '='"),
    ("x' = @", 6, "unexpected character '@'"),
    ("x' = 'x", 6, "prime"),
    ("= x", 1, "unexpected '='"),
    ("x'' = x + * 2", 11, "unexpected '*'"),
    ("x' = sin(x, y)", 11, "unexpected character ','"),
])
def test_syntax_errors_point_at_the_column(text, column, words):
    err = refusal(text)
    assert err.column == column
    assert words in err.message
    assert err.text == text


def test_syntax_error_on_a_later_line_names_the_line():
    err = refusal("x' = k\ny' = (3")
    assert err.column == 8 and err.message.startswith("line 2: ")
    assert err.text == "y' = (3"


@pytest.mark.parametrize("text, column", [("x' = foo(x)", 6), ("x' = -k*x + gamma(x)", 13)])
def test_unknown_function(text, column):
    err = refusal(text)
    assert err.column == column
    assert "unknown function" in err.message and "sin" in err.message


@pytest.mark.parametrize("text, column", [("x' = -k*t", 9), ("x' = sin(t)", 10), ("t' = 1", 1), ("x' = t(1)", 6)])
def test_time_is_refused(text, column):
    err = refusal(text)
    assert err.column == column and "autonomous" in err.message


@pytest.mark.parametrize("text, column", [("x'' = x''", 7), ("x' = x'' - x", 6), ("x'' = -x - x'''", 12),
                                          ("dx/dt = dx/dt", 9)])
def test_rhs_derivative_not_below_lhs_order(text, column):
    err = refusal(text)
    assert err.column == column and "order" in err.message


def test_rhs_derivative_of_another_state_at_its_own_order():
    err = refusal("x'' = -k*x; y'' = x''")
    assert err.column == 19 and "x's equation is for x''" in err.message


def test_state_with_no_equation():
    err = refusal("x' = y'")
    assert err.column == 6 and "y has no equation" in err.message


def test_state_with_two_equations():
    err = refusal("x' = 1; x' = 2")
    assert err.column == 9 and "two equations for x" in err.message


def test_equation_naming_no_state():
    err = refusal("a = b")
    assert err.column == 1 and "names no state" in err.message
    err = refusal("x' = -x; a = b")
    assert err.column == 10 and "names no state" in err.message


def test_lone_state_without_a_derivative():
    err = refusal("x' = 1; x = 3")
    assert err.column == 9 and "has no derivative" in err.message


@pytest.mark.parametrize("text", ["", "   ", ";;\n", "\n\n", "# just a comment"])
def test_empty_text(text):
    err = refusal(text)
    assert err.column is None and "empty" in err.message


def test_too_long():
    err = refusal("x' = " + "x + " * 600 + "x")
    assert "too long" in err.message and str(MAX_LENGTH) in err.message


def test_too_deep():
    err = refusal("x' = " + "sin(" * 80 + "x" + ")" * 80)
    assert "nested too deeply" in err.message


@pytest.mark.parametrize("text, column", [("x' = sin", 6), ("x' = -exp*x", 7), ("sqrt' = 1", 1)])
def test_name_colliding_with_a_function(text, column):
    err = refusal(text)
    assert err.column == column and "function name" in err.message


@pytest.mark.parametrize("text", ["e' = 1", "pi' = 1"])
def test_math_constant_as_state(text):
    err = refusal(text)
    assert err.column == 1 and "needs another name" in err.message


@pytest.mark.parametrize("text, words", [
    ("x''^2 = x", "power 2"),
    ("x''^3 = x", "power 3"),
    ("sin(x'') = x", "sin is not one-to-one"),
    ("abs(x'') = 1", "abs is not one-to-one"),
    ("x''*sin(x'') = 1", "no unique"),
    ("x'' + y'' = 0; y' = 1", "cannot tell which derivative"),
    ("x' + x = x' + 1", "cancel out"),
])
def test_implicit_forms_without_a_unique_solution(text, words):
    err = refusal(text)
    assert words in err.message
    assert err.column is not None


def test_division_by_zero_and_complex_values():
    assert "not finite" in refusal("x' = 1/0").message
    assert "complex" in refusal("x' = sqrt(-1)").message


def test_dx_dt_with_mismatched_orders():
    err = refusal("d2x/dt = 1")
    assert err.column == 1 and "differ" in err.message


@pytest.mark.parametrize("kw, words", [
    ({"fix": {"q": 1.0}}, "no constant named q"),
    ({"free": ["q"]}, "no constant named q"),
    ({"fix": {"x": 1.0}}, "state variable"),
    ({"free": ["pi"]}, "mathematical constant"),
    ({"fix": {"g": float("nan")}}, "finite"),
    ({"fix": {"g": "fast"}}, "not a number"),
    ({"fix": {"g": 9.81}, "free": ["g"]}, "both fixed and freed"),
])
def test_fix_and_free_must_name_constants_of_the_equation(kw, words):
    err = refusal("x'' = -g/L*sin(x)", **kw)
    assert words in err.message
    assert err.column is None


def test_error_is_a_fitode_error_with_one_line():
    from fitode.errors import FitodeError
    err = refusal("x' = y'\n")
    assert isinstance(err, FitodeError)
    assert "\n" not in str(err) and str(err).endswith("(column 6)")


@pytest.mark.parametrize("text", ["x' = exp(1e300)*x", "x' = -x*sin(-2e7)", "x' = x*cosh(sqrt(1e300))"])
def test_function_of_a_huge_number_is_refused_in_one_line(text):
    # sympy would evaluate exp(1e300) at once, in mpmath, for hours
    with pytest.raises(EquationError, match=r"a function of a number beyond 1e\+06"):
        parse(text)


# --- did you mean ------------------------------------------------------------------------------


@pytest.mark.parametrize("text, name, state", [
    ("theta'' = -g/L*sin(teta)", "teta", "theta"),      # a letter dropped
    ("omega' = -k*omgea", "omgea", "omega"),            # two letters swapped
    ("phi'' = -k*phii - c*phi'", "phii", "phi"),        # a letter doubled
    ("x' = v; vel' = -k*x - c*veel", "veel", "vel"),    # in a system
])
def test_a_constant_named_like_a_state_is_refused_with_the_state(text, name, state):
    err = refusal(text)
    assert f"'{name}' is not a state: did you mean '{state}'?" in err.message
    assert text[err.column - 1:].startswith(name)
    assert f"--free {name}" in err.message  # how to keep it on purpose
    # said on purpose (freed, fixed or an equation file's parameter), it stays a constant
    assert name in parse(text, free=[name]).learnable
    assert name in parse(text, fix={name: 1.0}).fixed
    assert name in parse(text, declared=[name]).learnable


@pytest.mark.parametrize("text", [
    "theta'' = -w^2*(theta - theta0)",        # an indexed relative of the state
    "beta'' = -zeta*beta' - eta*beta",        # Greek letters: both meant
    "u' = a*u - b*u*v; v' = -c*v + d*u*v",    # one-letter names are too short to be typos
    "x'' = -k*x - mu*x'",
])
def test_deliberate_names_near_a_state_are_kept(text):
    s = parse(text)
    assert s.learnable and s.hints == ()


def test_a_constant_inside_sin_where_a_state_is_expected_gets_a_hint():
    s = parse("x'' = -k*sin(y)")
    assert s.learnable == ("k", "y")  # accepted: a hint, not a refusal
    assert s.hints == ("'y' inside sin(...) is a constant to learn, not a state; "
                       "if you meant the state x, write sin(x)",)
    # an angle that is meant (an incline's), a state inside, or no states at all: no hint
    assert parse("x'' = g*(sin(alpha) - mu*cos(alpha))", declared=["alpha", "mu"]).hints == ()
    assert parse("x'' = -k*sin(x + a)").hints == ()
    assert parse("x'' = -k*cos(x')").hints == ()


def test_eqparse_stays_torch_free_with_the_typo_rules():
    import subprocess
    import sys
    code = "import sys, fitode.eqparse.typos, fitode.eqparse; assert 'torch' not in sys.modules"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
