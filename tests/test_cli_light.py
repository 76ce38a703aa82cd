"""Light commands never import torch (seconds of start-up for a help text or an equation check),
and every bad option is one line, status 2, naming the option, before anything heavy runs."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from fitode.cli import main


def _fresh(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_help_check_and_list_do_not_import_torch():
    code = ("import fitode.cli, sys\n"
            "fitode.cli.main(['check', '--list'])\n"
            "fitode.cli.main(['--help'])\n"
            "fitode.cli.main(['check', '--eq', \"x'' = -k*x\"])\n"
            "assert 'torch' not in sys.modules, 'torch was imported'\n"
            "print('ok')\n")
    r = _fresh(code)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr


def test_every_verbs_help_and_the_batch_driver_do_not_import_torch(tmp_path):
    (tmp_path / "a.json").write_text("{}")
    manifest = tmp_path / "v.csv"
    manifest.write_text("video,setting\na.json,A\n")
    code = ("import fitode.cli, sys\n"
            "for verb in ('run', 'check', 'codegen', 'batch', 'bench'):\n"
            "    try:\n"
            "        fitode.cli.main([verb, '--help'])\n"
            "    except SystemExit:\n"
            "        pass\n"
            f"assert fitode.cli.main(['batch', {str(manifest)!r}, '--dry-run', '--eq', \"I' = -k*I\", "
            "'--restarts', '2']) == 0\n"
            "assert fitode.cli.main(['VIDEO.mp4', '--eq', \"I' = -k*I\", '--window', '2']) == 2\n"
            "assert 'torch' not in sys.modules, 'torch was imported'\n"
            "print('ok')\n")
    r = _fresh(code)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr


def test_a_run_whose_equation_or_video_is_bad_fails_without_importing_torch(tmp_path):
    """torch comes with the plan, after the read: a typo, a missing or an unreadable video is one
    line and status 2 in the time of the parse and the read (seconds less)."""
    (tmp_path / "notes.mp4").write_text("not a video")
    eq = "x'' = -k*x"
    cases = [[str(tmp_path / "missing.mp4"), "--eq", eq], [str(tmp_path / "notes.mp4"), "--eq", eq],
             [str(tmp_path / "notes.mp4"), "--eq", "x'' = -k*"]]
    code = ("import fitode.cli, sys\n"
            f"codes = [fitode.cli.main(argv + ['--out', {str(tmp_path / 'out')!r}]) for argv in {cases!r}]\n"
            "assert codes == [2, 2, 2], codes\n"
            "assert 'torch' not in sys.modules, 'torch was imported'\n"
            "print('ok')\n")
    r = _fresh(code)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 3 and all(line.startswith("fitode: error: ") for line in lines), lines
    assert "no such file" in lines[0] and "cannot read it as a video" in lines[1] and "column" in lines[2]


BAD = [
    (["--restarts", "0"], "--restarts"),
    (["--max-steps", "-1"], "--max-steps"),
    (["--max-steps", "many"], "--max-steps"),
    (["--encoder", "foo"], "--encoder"),
    (["--window", "2"], "--window"),
    (["--prior", "0,-1"], "--prior"),
    (["--prior", "1"], "--prior"),
    (["--train-fraction", "2"], "--train-fraction"),
    (["--train-fraction", "0"], "--train-fraction"),
    (["--integrator", "nope"], "--integrator"),
    (["--device", "tpu"], "--device"),
    (["--threads", "0"], "--threads"),
    (["--seed", "-1"], "--seed"),
    (["--workers", "2"], "--workers"),  # restarts train as one batched model: no worker processes
]


def _one_line_error(capsys, argv, flag):
    code = main(argv)
    out, err = capsys.readouterr()
    lines = err.strip("\n").split("\n")
    assert code == 2, (argv, err)
    assert len(lines) == 1 and lines[0].startswith("fitode: error: ") and flag in lines[0], (argv, err)
    assert "Traceback" not in err and out == ""


@pytest.mark.parametrize("extra,flag", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_option_of_fitode_video_is_one_line_naming_it(extra, flag, capsys, tmp_path):
    # the video does not exist: the option must be refused before anyone looks for it
    _one_line_error(capsys, [str(tmp_path / "nope.mp4"), "--eq", "I' = -k*I", *extra], flag)


BATCH_BAD = [(a, f) for a, f in BAD if f not in ("--prior", "--train-fraction", "--device", "--threads", "--workers")]
BATCH_BAD += [(["--workers", "0"], "--workers"), (["--min-steps", "-1"], "--min-steps"),
              (["--const", "k"], "--const"), (["--init", "k=x"], "--init"), (["--free", "2k"], "--free")]


@pytest.mark.parametrize("extra,flag", BATCH_BAD, ids=[" ".join(a) for a, _ in BATCH_BAD])
def test_bad_option_of_fitode_batch_is_one_line_naming_it(extra, flag, capsys, tmp_path):
    (tmp_path / "a.json").write_text("{}")
    manifest = tmp_path / "v.csv"
    manifest.write_text("video,setting\na.json,A\n")
    _one_line_error(capsys, ["batch", str(manifest), "--dry-run", "--eq", "I' = -k*I", *extra], flag)


@pytest.mark.parametrize("argv,flag", [
    (["check", "--eq", "x'' = -k*x", "--const", "k"], "--const"),
    (["check", "--eq", "x'' = -k*x", "--free", "1x"], "--free"),
    (["codegen", "--eq", "x'' = -k*x", "--const", "k=nan"], "--const"),
    (["codegen", "--eq", "x'' = -k*x", "--integrator", "nope"], "--integrator"),
    (["synth", "equation", "--eq", "x'' = -k*x", "--const", "k=x", "--y0", "x=1", "--out",
      "never-written.npy"], "--const"),
])
def test_bad_equation_option_of_other_verbs_is_one_line_naming_it(argv, flag, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _one_line_error(capsys, argv, flag)
    assert not Path("never-written.npy").exists()


def test_batch_flags_become_manifest_defaults(capsys, tmp_path):
    (tmp_path / "a.json").write_text("{}")
    manifest = tmp_path / "v.csv"
    manifest.write_text("video,setting\na.json,A\n")
    code = main(["batch", str(manifest), "--dry-run", "--eq", "I' = -k*I - c*I", "--const", "c=0.1",
                 "--init", "k=0.3", "--restarts", "2", "--min-steps", "5"])
    out = capsys.readouterr().out
    assert code == 0
    assert "const={'c': 0.1}" in out and "init={'k': 0.3}" in out and "restarts=2" in out and "min_steps=5" in out


@pytest.mark.parametrize("argv,said", [
    (["v.mp4", "--sytem", "pendulum"], "unknown flag --sytem (did you mean --system?)"),
    (["v.mp4", "--eq", "x'' = -k*x", "--max-steps=3", "--restrats", "2"], "unknown flag --restrats (did you mean --restarts?)"),
    # a prefix is no abbreviation: argparse would take --restart for --restarts without a word
    (["v.mp4", "--eq", "x'' = -k*x", "--restart", "2"], "unknown flag --restart (did you mean --restarts?)"),
    (["v.mp4", "--eq", "x'' = -k*x", "--max-step=3"], "unknown flag --max-step (did you mean --max-steps?)"),
    (["synth", "scene", "pendulum", "--dur", "2"], "fitode synth scene: unknown flag --dur (did you mean --duration?)"),
    (["batch", "m.csv", "--dryrun"], "fitode batch: unknown flag --dryrun (did you mean --dry-run?)"),
    (["check", "--eq", "x'' = -k*x", "--zzzz"], "fitode check: unknown flag --zzzz (see fitode check -h)"),
    (["synth", "paper", "motion", "--outt", "x.npy"], "fitode synth paper: unknown flag --outt (did you mean --out?)"),
])
def test_an_unknown_flag_names_itself_and_its_nearest_flag(argv, said, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing exists: the flag is refused before anything is looked at
    _one_line_error(capsys, argv, said)


def test_a_typo_of_a_state_is_one_line_status_2(capsys, tmp_path):
    _one_line_error(capsys, [str(tmp_path / "nope.mp4"), "--eq", "theta'' = -g/L*sin(teta)"],
                    "'teta' is not a state: did you mean 'theta'?")
    _one_line_error(capsys, ["check", "--eq", "theta'' = -g/L*sin(teta)"], "did you mean 'theta'?")
    assert main(["check", "--eq", "theta'' = -g/L*sin(teta)", "--free", "teta"]) == 0
    assert "learnable constants:" in capsys.readouterr().out
