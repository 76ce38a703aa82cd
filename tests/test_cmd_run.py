"""`fitode VIDEO ...`: every error path (status 2, one line on stderr), the output folder, --json, --quiet.

Videos are tiny mp4s written here with OpenCV (fitode.examples.make_example's renderers); the
training runs are a few dozen steps, enough to exercise the plumbing. Accuracy is checked in
test_cmd_run_e2e.py.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fitode.cli import main
from fitode.examples.make_example import decay_values, render_glow, write_mp4

EQ = "I' = -gamma*I"
TINY = ["--restarts", "2", "--max-steps", "12", "--window", "8", "--stride", "1"]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("cmd-run")
    return write_mp4(folder / "glow.mp4", render_glow(decay_values(40, 10.0, 0.5), size=16), 10.0)


@pytest.fixture(scope="module")
def short_video(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("cmd-run-short")
    return write_mp4(folder / "short.mp4", render_glow(decay_values(10, 10.0, 0.5), size=16), 10.0)


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_png(path: Path) -> None:
    import cv2
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC, path
    assert cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR) is not None, path


# ----------------------------------------------------------------------------- errors
def error_cases(tmp: Path, video: Path, short: Path) -> dict[str, list]:
    (tmp / "not-a-video.mp4").write_bytes(b"this is not a video" * 100)
    np.save(tmp / "empty.npy", np.zeros((0, 8, 8), np.uint8))
    full = tmp / "full"
    full.mkdir(exist_ok=True)
    (full / "keep.txt").write_text("an earlier run")
    eq = ["--eq", EQ]
    return {
        "missing file": [tmp / "nope.mp4", *eq],
        "unreadable video": [tmp / "not-a-video.mp4", *eq],
        "zero frames": [tmp / "empty.npy", "--fps", "10", *eq],
        "fewer frames than a window": [short, *eq, "--stride", "1", "--window", "20"],
        "unknown flag": [video, *eq, "--bogus"],
        "no equation": [video],
        "two equations": [video, *eq, "--system", "pendulum"],
        "restarts 0": [video, *eq, "--restarts", "0"],
        "max-steps text": [video, *eq, "--max-steps", "many"],
        "bad integrator": [video, *eq, "--integrator", "leapfrog"],
        "bad encoder": [video, *eq, "--encoder", "vit"],
        "bad roi": [video, *eq, "--roi", "1,2,3"],
        "roi outside": [video, *eq, "--roi", "0,0,100,100"],
        "bad size": [video, *eq, "--size", "64"],
        "bad stride": [video, *eq, "--stride", "0"],
        "bad fps": [video, *eq, "--fps", "-3"],
        "start after end": [video, *eq, "--start", "3", "--end", "1"],
        "bad prior": [video, *eq, "--prior", "1"],
        "prior std 0": [video, *eq, "--prior", "0,0"],
        "bad const": [video, *eq, "--const", "gamma"],
        "bad init name": [video, *eq, "--init", "beta=1"],
        "bad train fraction": [video, *eq, "--train-fraction", "1.5"],
        "window too short": [video, *eq, "--window", "2"],
        "workers is gone": [video, *eq, "--workers", "2"],
        "equation syntax": [video, "--eq", "I' = -gamma*"],
        "equation with t": [video, "--eq", "I' = -gamma*I*t"],
        "missing eq file": [video, "--eq-file", tmp / "nope.toml"],
        "unknown system": [video, "--system", "no-such-system"],
        "calibrate unknown state": [video, *eq, "--calibrate", "h(0)=1; h(1)=0.5"],
        "calibrate outside clip": [video, *eq, "--calibrate", "I(0)=1; I(60)=0.5"],
        "calibrate one point": [video, *eq, "--calibrate", "I(0)=1"],
        "out not empty": [video, *eq, "--out", full],
        "out through a file": [video, *eq, "--out", tmp / "not-a-video.mp4" / "sub"],
        "out in /proc": [video, *eq, "--out", "/proc/fitode-out"],
        "cuda without cuda": [video, *eq, "--device", "cuda"],
    }


CASES = ["missing file", "unreadable video", "zero frames", "fewer frames than a window", "unknown flag",
         "no equation", "two equations", "restarts 0", "max-steps text", "bad integrator", "bad encoder", "bad roi",
         "roi outside", "bad size", "bad stride", "bad fps", "start after end", "bad prior", "prior std 0",
         "bad const", "bad init name", "bad train fraction", "window too short", "workers is gone", "equation syntax", "equation with t",
         "missing eq file", "unknown system", "calibrate unknown state", "calibrate outside clip",
         "calibrate one point", "out not empty", "out through a file", "out in /proc", "cuda without cuda"]


@pytest.mark.parametrize("case", CASES)
def test_error_paths_exit_2_with_one_line(case, video, short_video, tmp_path, capsys, monkeypatch):
    if case == "cuda without cuda":
        import torch
        if torch.cuda.is_available():
            pytest.skip("CUDA is available here")
    monkeypatch.chdir(tmp_path)  # a run that wrongly went ahead would write under ./fitode-runs here
    argv = error_cases(tmp_path, video, short_video)[case]
    code, out, err = run(argv, capsys)
    assert code == 2, (case, out, err)
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1 and lines[0].startswith("fitode: error: "), (case, err)
    assert out == ""
    assert not (tmp_path / "fitode-runs").exists()  # nothing was started


@pytest.mark.parametrize("eq, extra, words", [
    ("y'' = -g", [], "g is the known 9.80665, fixed unless freed; --free g"),
    ("I' = -gamma*I", ["--const", "gamma=2"], "every name is fixed (gamma, by --const"),
    ("y'' = -y", [], "no constant to estimate: write one into it"),
])
def test_an_equation_with_nothing_to_estimate_says_how_to_estimate_one(eq, extra, words, video, tmp_path, capsys,
                                                                       monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run([video, "--eq", eq, *extra], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and words in err, err


@pytest.mark.parametrize("where", ["file/sub", "/proc/fitode-out"])
def test_an_unwritable_out_fails_before_the_video_is_read(where, video, tmp_path, capsys, monkeypatch):
    import fitode.pipeline

    monkeypatch.chdir(tmp_path)
    (tmp_path / "file").write_text("a file, not a folder")
    monkeypatch.setattr(fitode.pipeline, "read_clip", lambda *a, **k: pytest.fail("the video was read"))
    code, out, err = run([video, "--eq", EQ, "--out", where], capsys)
    assert code == 2 and err.count("\n") == 1 and f"--out {where}: cannot write there" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # nothing made, nothing left


def test_existing_out_dir_is_never_touched(video, tmp_path, capsys):
    full = tmp_path / "run"
    full.mkdir()
    (full / "result.json").write_text("{\"mine\": true}")
    code, _, err = run([video, "--eq", EQ, "--out", full, *TINY], capsys)
    assert code == 2 and "not empty" in err
    assert sorted(p.name for p in full.iterdir()) == ["result.json"]
    assert json.loads((full / "result.json").read_text()) == {"mine": True}


def test_errors_in_a_real_process_stay_one_line(tmp_path):
    """OpenCV and FFmpeg may print from C; the user must still see exactly one line."""
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00\x00\x00\x18ftypmp42" + b"garbage" * 200)
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    for argv in ([str(bad), "--eq", EQ], [str(bad), "--eq", EQ, "--restarts", "x"]):
        p = subprocess.run([sys.executable, "-m", "fitode", *argv], capture_output=True, text=True, env=env,
                           cwd=tmp_path, timeout=120)
        assert p.returncode == 2, (argv, p.stderr)
        assert len(p.stderr.strip().splitlines()) == 1, (argv, p.stderr)
        assert p.stdout == ""


# ----------------------------------------------------------------------------- a run
def test_run_writes_the_folder_and_json_goes_to_stdout(video, tmp_path, capsys):
    out_dir = tmp_path / "out"
    # the encoder's training (--observe any): its settings and history are what this run records
    code, out, err = run([video, "--eq", EQ, "--out", out_dir, "--json", "--init", "gamma=0.3", "--observe", "any",
                          *TINY], capsys)
    assert code == 0, err
    report = json.loads(out)  # stdout is pure JSON
    assert report == json.loads((out_dir / "result.json").read_text())
    assert report["status"] == "complete"
    assert "estimates" in err and "equation: I' = " in err  # the human text went to stderr
    est = report["parameters"]["gamma"]
    assert math.isfinite(est["value"]) and math.isfinite(est["std"]) and est["n_runs"] >= 1
    assert report["input"]["name"] == "glow.mp4" and len(report["input"]["sha256"]) == 64
    assert report["input"]["fps"] == 10 and report["input"]["fps_source"] == "container"
    assert report["input"]["stride"] == 1 and report["input"]["dt"] == pytest.approx(0.1)
    assert report["fitode_version"]
    assert report["runs"][0]["init"]["gamma"] == 0.3  # the user's start is restart 1's; the others come from the data or a spread
    assert {"init", "final", "loss", "steps", "status", "error"} <= set(report["runs"][0])
    assert report["settings"]["restarts"] == 2 and report["settings"]["window"] == 8
    assert report["settings"]["max_steps"] == 12
    for name in ("latent.png", "params.png", "loss.png", "frames.png"):
        assert_png(out_dir / name)
    from fitode.train.result import FitResult
    fit = FitResult.load(out_dir / "fit.json")
    assert len(fit.runs[0].history.loss) == fit.runs[0].steps


def test_quiet_prints_only_the_table_and_calibration_is_recorded(video, tmp_path, capsys):
    code, out, err = run([video, "--eq", EQ, "--out", tmp_path / "q", "--quiet", *TINY,
                          "--calibrate", "I(0)=1; I(3.5)=0.17"], capsys)
    assert code == 0, err
    assert out.startswith("estimates (mean over") and "gamma" in out
    assert "equation:" not in out and "fps:" not in out and err == ""
    assert "calibration: I = " in out
    report = json.loads((tmp_path / "q" / "result.json").read_text())
    cal = report["calibration"]
    assert [p["time"] for p in cal["points"]] == [0.0, 3.5] and set(cal["maps"]) == {"I"}
    assert cal["maps"]["I"]["a"] != 0 and set(cal["constants"]) == {"gamma"}
    assert report["trajectory"]["units"] == "physical"
    # a measured path fitted directly: its fitted trajectory, calibrated, passes through the points
    # (read from a local quadratic of it); the reading itself scatters about them
    from fitode.calibrate import local_value
    times = np.array(report["trajectory"]["time"])
    fitted = np.array(report["trajectory"]["rollout"], dtype=float)[:, 0]
    assert local_value(times, fitted, 0.0) == pytest.approx(1.0, abs=1e-6)
    assert local_value(times, fitted, 3.5) == pytest.approx(0.17, abs=1e-6)
    z = np.array(report["trajectory"]["latent"])[:, 0]
    assert abs(local_value(times, z, 0.0) - 1.0) > 1e-6


def test_default_out_dir_is_new_each_time(video, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for _ in range(2):
        code, _, err = run([video, "--eq", EQ, "--quiet", "--restarts", "1", "--max-steps", "3", "--window", "8",
                            "--stride", "1"], capsys)
        assert code == 0, err
    made = sorted((tmp_path / "fitode-runs").iterdir())
    assert len(made) == 2 and all(p.name.startswith("glow-") for p in made)
    assert all((p / "result.json").is_file() for p in made)


def test_help_lists_every_flag(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = capsys.readouterr().out
    for flag in ("--eq", "--eq-file", "--system", "--const", "--free", "--init", "--prior", "--restarts",
                 "--max-steps", "--integrator", "--encoder", "--device", "--seed", "--out", "--quiet", "--json",
                 "--fps", "--start", "--end", "--roi", "--size", "--color", "--stride", "--mask", "--calibrate",
                 "--train-fraction", "--window", "--threads"):
        assert flag in text, flag
    assert "--workers" not in text  # restarts train as one batched model, in this process
    assert "(default 4)" in text  # the restarts' default, read from fitode.train.config


def test_what_cannot_be_measured_fails_before_the_header_and_the_folder(tmp_path, capsys):
    """A lamp's light changes in place: no angle can be read off it, and that is said in one line
    with status 2 before anything is printed or written."""
    from fitode.synth import scene, write_video
    video = write_video(scene("led", size=(48, 64), duration=1.0, seed=1), tmp_path / "led.mp4")
    out = tmp_path / "out"
    code = main([str(video), "--eq", "I' = -gamma*I", "--observe", "angle", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2 and not out.exists()
    assert "angle observation" in captured.err and len(captured.err.strip().splitlines()) == 1
    assert "input:" not in captured.out + captured.err  # no header


def test_no_plots_writes_the_numbers_and_no_picture(video, tmp_path, capsys):
    code, _, err = run([video, "--eq", EQ, "--out", tmp_path / "plain", "--quiet", *TINY], capsys)
    assert code == 0, err
    code, _, err = run([video, "--eq", EQ, "--out", tmp_path / "bare", "--quiet", "--no-plots", *TINY], capsys)
    assert code == 0, err
    bare = json.loads((tmp_path / "bare" / "result.json").read_text())
    plain = json.loads((tmp_path / "plain" / "result.json").read_text())
    assert not list((tmp_path / "bare").glob("*.png")) and not [f for f in bare["files"] if f.endswith(".png")]
    assert list((tmp_path / "plain").glob("*.png"))  # the same run with its pictures
    assert {"result.json", "fit.json", "estimates.csv", "track.csv"} <= set(bare["files"])
    assert bare["parameters"]["gamma"]["value"] == plain["parameters"]["gamma"]["value"]
