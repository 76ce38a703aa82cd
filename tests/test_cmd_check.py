"""`fitode check` through the real entry point, and the NAME=VALUE option helpers."""
import pytest

from fitode.cli import main
from fitode.eqfile import list_systems
from fitode.errors import FitodeError
from fitode.names import parse_assignments, parse_names


def check(capsys, *args):
    code = main(["check", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_check_equation_text(capsys):
    code, out, err = check(capsys, "--eq", "x'' = -g/L*sin(x) - z*x'")
    assert code == 0 and err == ""
    assert "normal form:\n  x'' = -x'*z - g*sin(x)/L" in out
    assert "x  order 2" in out
    assert "fixed constants:\n  g = 9.80665" in out
    learnable = out.split("learnable constants:")[1].split("what a video can measure:")[0]
    assert learnable.split() == ["L", "z"]
    assert "free-small-amplitude" in out


def test_check_shipped_pendulum_shows_the_file(capsys):
    code, out, _ = check(capsys, "--system", "pendulum")
    assert code == 0
    assert out.startswith("pendulum: ")
    assert "L     init 1, bounds [0, inf], unit m" in out
    assert "prior on the latent: N(0, 1^2)" in out


def test_const_and_free_change_the_classification(capsys):
    _, out, _ = check(capsys, "--system", "pendulum", "--const", "g=9.81")
    assert "g = 9.81\n" in out
    _, out, _ = check(capsys, "--system", "pendulum", "--free", "g")
    assert "fixed constants: none" in out
    assert "only as g/L" in out
    _, out, _ = check(capsys, "--eq", "x'' = -g/L*sin(x) - z*x'", "--const", "g=9.81,L=2", "--const", "z=0.1")
    assert "learnable constants: none" in out and "nothing to estimate" in out


def test_sliding_block_reports_one_combination(capsys):
    _, out, _ = check(capsys, "--system", "sliding_block")
    assert "only as sin(alpha) - mu*cos(alpha)" in out
    assert "1 of 2 constants can be told apart" in out


def test_torricelli_reports_dependent_scale_and_its_prior(capsys):
    _, out, _ = check(capsys, "--system", "torricelli")
    assert "scale: dependent" in out
    assert "N(1, 0.2^2)" in out


def test_eq_file(capsys, tmp_path):
    path = tmp_path / "led.toml"
    path.write_text('name = "led"\nequation = "I\' = -gamma*I"\n[parameters]\ngamma = { init = 2.0, unit = "1/s" }\n')
    code, out, _ = check(capsys, "--eq-file", str(path))
    assert code == 0
    assert "gamma  init 2, unit 1/s" in out and "scale: free" in out


def test_list(capsys):
    code, out, _ = check(capsys, "--list")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert names == list_systems()
    assert "theta'' = -g/L*sin(theta) - zeta*theta'" in out


@pytest.mark.parametrize("name", list_systems())
def test_every_shipped_system_checks(capsys, name):
    code, out, err = check(capsys, "--system", name)
    assert code == 0 and err == ""
    assert "what a video can measure:" in out


@pytest.mark.parametrize("args, words", [
    (["--eq", "x'' = 2x"], "explicit '*' (column 8)"),
    (["--eq", "x' = -k*t"], "autonomous"),
    (["--eq", ""], "empty"),
    (["--system", "nope"], "available: "),
    (["--eq-file", "/does/not/exist.toml"], "not found"),
    (["--system", "pendulum", "--const", "g"], "NAME=VALUE"),
    (["--system", "pendulum", "--const", "g=fast"], "not a number"),
    (["--system", "pendulum", "--free", "q"], "no constant named q"),
    (["--system", "pendulum", "--const", "g=9.8", "--free", "g"], "both fixed and freed"),
    (["--eq", "x' = -x", "--system", "pendulum"], "not allowed with"),
    ([], "give one of --eq"),
])
def test_errors_are_one_line_with_status_2(capsys, args, words):
    code, out, err = check(capsys, *args)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("fitode: error: ")
    assert words in err


def test_parse_assignments():
    assert parse_assignments(["g=9.81", "L=1, z=0.1"]) == {"g": 9.81, "L": 1.0, "z": 0.1}
    assert parse_assignments(None) == {} and parse_assignments([]) == {}
    assert parse_assignments("k=2e-3") == {"k": 0.002}
    assert parse_assignments(["g=1", "g=1.0"]) == {"g": 1.0}


@pytest.mark.parametrize("items, words", [
    (["g"], "NAME=VALUE"), (["=1"], "NAME=VALUE"), (["g="], "NAME=VALUE"), (["1g=2"], "not a valid name"),
    (["g=x"], "not a number"), (["g=inf"], "finite"), (["g=1", "g=2"], "given twice"),
])
def test_parse_assignments_errors(items, words):
    with pytest.raises(FitodeError, match=words):
        parse_assignments(items, "--init")


def test_parse_names():
    assert parse_names(["g", "L,z", "g"]) == ["g", "L", "z"]
    assert parse_names(None) == []
    with pytest.raises(FitodeError, match="--free"):
        parse_names(["g=1"])
