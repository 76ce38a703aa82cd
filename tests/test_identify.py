"""Identifiability: which constants a latent can measure, and whether they depend on its scale."""
import pytest

from fitode.eqparse import analyse, parse
from fitode.eqparse.identify import SCALES


def report(text, **kw):
    return analyse(parse(text, **kw))


def test_pendulum_with_g_known():
    r = report("theta'' = -g/L*sin(theta) - zeta*theta'")
    assert [c.name for c in r.constants] == ["L", "zeta"]
    assert r["L"].separable and r["L"].combination is None
    assert r["L"].scale == "free-small-amplitude"
    assert "small-amplitude" in r["L"].reason
    assert r["zeta"].separable
    assert r.rank == 2


def test_pendulum_with_g_freed_measures_only_g_over_l():
    r = report("theta'' = -g/L*sin(theta) - zeta*theta'", free=["g"])
    assert not r["g"].separable and not r["L"].separable
    assert r["g"].combination == r["L"].combination == "g/L"
    assert r["zeta"].separable
    assert r.rank == 2


def test_torricelli_k_depends_on_scale():
    r = report("h' = -k*sqrt(h)")
    assert r["k"].separable
    assert r["k"].scale == "dependent"
    assert "rescaled" in r["k"].reason


def test_led_decay_rate_is_scale_free():
    r = report("I' = -gamma*I")
    assert r["gamma"].separable and r["gamma"].scale == "free"


def test_sliding_block_has_one_combination():
    r = report("x'' = g*(sin(alpha) - mu*cos(alpha))")
    assert r.rank == 1
    for name in ("alpha", "mu"):
        assert not r[name].separable
        assert r[name].combination == "sin(alpha) - mu*cos(alpha)"
        assert r[name].scale == "dependent"  # a constant acceleration is in the latent's units
    assert any("1 of 2" in line for line in r.lines())


def test_sliding_block_with_alpha_fixed_measures_mu():
    r = report("x'' = g*(sin(alpha) - mu*cos(alpha))", fix={"alpha": 0.3})
    assert r["mu"].separable


def test_damped_oscillator_both_free():
    r = report("z'' + g1*z' + g0*z = 0")
    for name in ("g0", "g1"):
        assert r[name].separable and r[name].scale == "free"


def test_mass_spring_gives_k_over_m():
    r = report("x'' = -k/m*x")
    assert r["k"].combination == r["m"].combination == "k/m"
    assert r["k"].scale == "free"


def test_two_independent_groups_are_named_separately():
    r = report("x'' = -k/m*x - c*d*x'")
    assert r["k"].combination == "k/m"
    assert r["c"].combination == "c*d"
    assert r.rank == 2


def test_free_fall_g_depends_on_scale():
    r = report("d'' = g", free=["g"])
    assert r["g"].separable and r["g"].scale == "dependent"


@pytest.mark.parametrize("text, free_names, dependent_names", [
    ("u' = a*u - b*u*v; v' = -c*v + d*u*v", {"a", "c"}, {"b", "d"}),
    ("x' = r*x*(1 - x/K)", {"r"}, {"K"}),
    ("x'' + delta*x' + alpha*x + beta*x^3 = 0", {"delta", "alpha"}, {"beta"}),
    ("T' = -k*(T - Ta)", {"k"}, {"Ta"}),
])
def test_scale_classification_of_classic_systems(text, free_names, dependent_names):
    r = report(text)
    assert {c.name for c in r.constants if c.scale == "free"} == free_names
    assert {c.name for c in r.constants if c.scale == "dependent"} == dependent_names
    assert all(c.separable for c in r.constants)


def test_van_der_pol_is_free_at_small_amplitude():
    r = report("x'' = mu*(1 - x^2)*x' - x")
    assert r["mu"].scale == "free-small-amplitude"


def test_a_known_constant_pins_the_scale():
    # g fixes the units of v, so the drag coefficient is measured in them
    r = report("v' = -g - c*v*abs(v)")
    assert r["c"].scale == "free"
    assert "known constant g" in r["c"].reason
    # with g learnable the same drag coefficient is tied to the latent's units
    assert report("v' = -g - c*v*abs(v)", free=["g"])["c"].scale == "dependent"


def test_constant_that_cancels_is_not_measurable():
    r = report("x' = k - k + x")
    assert not r["k"].separable
    assert "does not appear" in r["k"].reason


def test_combination_that_cannot_be_named_is_counted():
    r = report("x' = sin(k*m*x)")
    assert not r["k"].separable
    assert r["k"].combination == "1 combination of k and m"


def test_no_learnable_constants():
    r = report("x'' = -g*x")
    assert r.constants == () and r.lines() == ["no learnable constants: nothing to estimate"]


def test_analysis_is_deterministic():
    a = report("u' = a*u - b*u*v; v' = -c*v + d*u*v")
    b = report("u' = a*u - b*u*v; v' = -c*v + d*u*v")
    assert a == b


def test_lines_show_every_constant_and_its_scale():
    r = report("theta'' = -g/L*sin(theta) - zeta*theta'")
    text = "\n".join(r.lines())
    assert all(c.scale in SCALES for c in r.constants)
    assert "L " in text and "zeta" in text and "free-small-amplitude" in text


def test_linear_first_order_equation_warns_about_nonlinear_encoders():
    for text in ("I' = -gamma*I", "I' = -gamma*(I - c)"):
        assert any("nonlinear encoder" in n and "linear" in n for n in report(text).notes), text
    for text in ("h' = -k*sqrt(h)", "z'' + g1*z' + g0*z = 0", "x' = r*x*(1 - x/K)"):
        assert not any("nonlinear encoder" in n for n in report(text).notes), text


@pytest.mark.parametrize("text, free, expected", [
    ("d'' = g", ["g"], {"g": {"d": 1.0}}),
    ("h' = -k*sqrt(h)", None, {"k": {"h": 0.5}}),
    ("x'' = -w2*x", None, {"w2": {"x": 0.0}}),
    ("x' = a*x + b*x^2", None, {"a": {"x": 0.0}, "b": {"x": -1.0}}),
    ("theta'' = -g/L*sin(theta)", None, {"L": None}),  # the angle's scale is no power of anything
])
def test_the_power_of_the_scale_each_constant_moves_by(text, free, expected):
    from fitode.eqparse.identify import scale_exponents
    system = parse(text, free=free) if free else parse(text)
    assert scale_exponents(system) == expected


def test_the_report_is_kept_per_equation_and_its_fixed_values():
    # one run asks three times; a parse of the same text gives the same report, a changed fixed
    # value or another seed a new one
    eq = "theta'' = -g/L*sin(theta) - zeta*theta'"
    first = analyse(parse(eq))
    assert analyse(parse(eq)) is first
    assert analyse(parse(eq, fix={"g": 9.0})) is not first
    assert analyse(parse(eq), seed=1) is not first
    assert analyse(parse(eq, fix={"g": 9.0}))["L"].scale == first["L"].scale
