"""Equation files: every shipped system loads, parses and is analysed; bad files fail clearly."""
from pathlib import Path

import pytest

from fitode.eqfile import EquationSpec, list_systems, load_equation_file, load_system, resolve
from fitode.eqparse import ParamSpec, analyse
from fitode.errors import FitodeError

PAPER = {"damped_oscillator", "pendulum", "torricelli", "sliding_block", "led_decay", "free_fall_scale",
         "spring_two_body"}


def test_every_system_of_the_paper_and_five_more_ship():
    names = list_systems()
    assert PAPER <= set(names)
    assert len(set(names) - PAPER) >= 5
    assert names == sorted(names)


@pytest.mark.parametrize("name", list_systems())
def test_shipped_file_loads_parses_and_is_analysed(name):
    spec = load_system(name)
    assert isinstance(spec, EquationSpec)
    assert spec.name == name
    assert spec.description
    assert spec.path and Path(spec.path).name == f"{name}.toml"
    system, again = resolve(system=name)
    assert again == spec
    assert system.learnable, "a shipped system has something to estimate"
    assert set(spec.parameters) == set(system.learnable), "every learnable constant is described"
    for p in spec.parameters.values():
        assert p.init is not None
    assert set(spec.constants) <= set(system.fixed)
    assert spec.prior_std > 0
    report = analyse(system)
    assert [c.name for c in report.constants] == list(system.learnable)


def test_pendulum_file():
    spec = load_system("pendulum")
    assert spec.equation == "theta'' = -g/L*sin(theta) - zeta*theta'"
    assert spec.constants == {"g": 9.80665}
    assert spec.parameters["L"] == ParamSpec(init=1.0, min=0.0, max=None, unit="m")
    system, _ = resolve(system="pendulum")
    assert system.fixed == {"g": 9.80665} and system.learnable == ("L", "zeta")


def test_torricelli_prior_is_the_papers():
    spec = load_system("torricelli")
    assert (spec.prior_mean, spec.prior_std) == (1.0, 0.2)


def test_free_fall_frees_g_through_its_parameters():
    system, spec = resolve(system="free_fall_scale")
    assert "g" in spec.parameters
    assert system.learnable == ("g",) and system.fixed == {}
    assert analyse(system)["g"].scale == "dependent"


def test_spring_two_body_has_four_second_order_states():
    system, _ = resolve(system="spring_two_body")
    assert system.states == ("x1", "y1", "x2", "y2")
    assert set(system.orders.values()) == {2}
    assert system.learnable == ("k", "l")


def test_caller_overrides_the_file():
    system, _ = resolve(system="pendulum", const={"g": 9.81})
    assert system.fixed == {"g": 9.81}
    system, _ = resolve(system="pendulum", free=["g"])
    assert system.learnable == ("g", "L", "zeta") and system.fixed == {}
    system, _ = resolve(system="pendulum", const={"L": 0.5})
    assert system.learnable == ("zeta",) and system.fixed["L"] == 0.5
    system, _ = resolve(system="free_fall_scale", const={"g": 9.81})
    assert system.learnable == () and system.fixed == {"g": 9.81}
    system, _ = resolve(system="pendulum", free=["g,zeta"])  # comma lists are accepted
    assert "g" in system.learnable


def test_resolve_text():
    system, spec = resolve(eq="x' = -k*x", const={"k": 2.0})
    assert spec is None and system.fixed == {"k": 2.0}


@pytest.mark.parametrize("kw", [{}, {"eq": "x' = -x", "system": "pendulum"},
                                {"eq": "x' = -x", "eq_file": "a.toml", "system": "pendulum"}])
def test_resolve_needs_exactly_one_source(kw):
    with pytest.raises(FitodeError, match="exactly one of --eq, --eq-file or --system"):
        resolve(**kw)


def test_unknown_system_lists_the_available_ones():
    with pytest.raises(FitodeError) as info:
        load_system("pendulumm")
    assert "pendulumm" in str(info.value) and "pendulum," in str(info.value)


def write(tmp_path, text: str) -> Path:
    path = tmp_path / "sys.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_user_file_round_trip(tmp_path):
    path = write(tmp_path, """
name = "cooling"
description = "a cooling cup"
equation = "T' = -k*(T - Ta)"
stride = 3
[constants]
Ta = 20.0
[parameters]
k = { init = 0.1, min = 0.0, max = 5.0, unit = "1/s" }
[prior]
mean = 1.0
std = 0.5
""")
    spec = load_equation_file(path)
    assert spec == EquationSpec(name="cooling", equation="T' = -k*(T - Ta)", constants={"Ta": 20.0},
                                parameters={"k": ParamSpec(0.1, 0.0, 5.0, "1/s")}, prior_mean=1.0, prior_std=0.5,
                                stride=3, description="a cooling cup", path=str(path))
    system, _ = resolve(eq_file=str(path))
    assert system.fixed == {"Ta": 20.0} and system.learnable == ("k",)


@pytest.mark.parametrize("body, words", [
    ('name = "a"\nequation = "x\' = -k*x"\ncolour = 1\n', "unknown key colour"),
    ('equation = "x\' = -k*x"\n', "'name' is missing"),
    ('name = "a"\n', "'equation' is missing"),
    ('name = "a"\nequation = "x\' = -k*x\n', "not valid TOML"),
    ('name = "a"\nequation = "x\' = -k*x"\n[parameters]\nq = { init = 1.0 }\n', "names q"),
    ('name = "a"\nequation = "x\' = -k*x"\n[constants]\nq = 1.0\n', "no constant named q"),
    ('name = "a"\nequation = "x\' = -k*x"\n[parameters]\nk = { init = 1.0, maxi = 2.0 }\n', "unknown key maxi"),
    ('name = "a"\nequation = "x\' = -k*x"\n[parameters]\nk = { init = "one" }\n', "must be a number"),
    ('name = "a"\nequation = "x\' = -k*x"\n[parameters]\nk = { init = 3.0, max = 2.0 }\n', "outside [min, max]"),
    ('name = "a"\nequation = "x\' = -k*x"\n[parameters]\nk = { min = 3.0, max = 2.0 }\n', "must be below max"),
    ('name = "a"\nequation = "x\' = -k*x"\n[prior]\nstd = 0.0\n', "std must be positive"),
    ('name = "a"\nequation = "x\' = -k*x"\n[prior]\nmedian = 0.0\n', "unknown key median"),
    ('name = "a"\nequation = "x\' = -k*x"\nstride = 0\n', "stride must be a positive"),
    ('name = "a"\nequation = "x\' = -k*t"\n', "autonomous"),
    ('name = "a"\nequation = "x\' = -k*x"\n[constants]\nk = 1.0\n[parameters]\nk = { init = 1.0 }\n',
     "both a fixed constant and a parameter"),
])
def test_bad_files_fail_with_the_path_and_the_reason(tmp_path, body, words):
    path = write(tmp_path, body)
    with pytest.raises(FitodeError) as info:
        load_equation_file(path)
    assert words in str(info.value)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(FitodeError, match="not found"):
        load_equation_file(tmp_path / "nope.toml")
