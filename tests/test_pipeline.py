"""fitode.pipeline.run_job (run_video with flat options): the folder it leaves in every outcome (complete, failed, interrupted)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fitode.errors import FitodeError
from fitode.examples.make_example import decay_values, render_glow, write_mp4
from fitode.pipeline import RunOutcome, _make_out_dir, run_job

EQ = "I' = -gamma*I"
TINY = dict(restarts=2, max_steps=10, window=8, stride=1)


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("pipeline")
    return write_mp4(folder / "glow.mp4", render_glow(decay_values(40, 10.0, 0.5), size=16), 10.0)


def test_run_video_returns_the_outcome(video, tmp_path):
    lines: list[str] = []
    seen = []
    # an encoder trained (observe "any"): the callback sees its steps (a measured light is fitted directly)
    out = run_job(video, tmp_path / "o", eq=EQ, log=lines.append, callback=seen.append, seed=1, observe="any",
                  **TINY)
    assert isinstance(out, RunOutcome) and out.out_dir == tmp_path / "o"
    assert out.report == json.loads((out.out_dir / "result.json").read_text())
    assert out.report["status"] == "complete" and out.warnings == out.report["warnings"]
    assert set(out.result.parameters) == {"gamma"}
    assert out.report["parameters"]["gamma"]["value"] == pytest.approx(out.result.parameters["gamma"].value)
    assert len(seen) == sum(r.steps for r in out.result.runs)  # the caller's callback saw every step
    text = "\n".join(lines)
    for what in ("fps: 10", "frames used: 40", "stride: 1", "dt: 0.1", "equation: I' = ", "learnable: gamma",
                 "training: 2 restarts"):
        assert what in text, what
    assert out.report["settings"]["seed"] == 1


def test_errors_come_before_any_folder(video, tmp_path):
    target = tmp_path / "never"
    for kwargs in (dict(eq="I' = -gamma*"), dict(eq=EQ, calibrate="q(0)=1; q(1)=2"),
                   dict(eq=EQ, init={"nope": 1.0}), dict(eq=EQ, window=50), dict(eq=EQ, restarts=0),
                   dict(eq=EQ, bogus=3), dict(eq=EQ, prior=(0.0, -1.0)), dict(eq=EQ, train_fraction=0.0),
                   dict(eq=EQ, encoder="vit")):
        with pytest.raises(FitodeError) as e:
            run_job(video, target, log=None, **{**TINY, **kwargs})
        assert "\n" not in str(e.value)
        assert not target.exists(), kwargs


def test_default_folders_are_unique(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    made = [_make_out_dir(None, "my clip") for _ in range(3)]
    assert len({p.name for p in made}) == 3
    assert all(p.parent == Path("fitode-runs") and p.name.startswith("my_clip-") for p in made)


def test_empty_out_dir_is_used(video, tmp_path):
    target = tmp_path / "empty"
    target.mkdir()
    out = run_job(video, target, eq=EQ, log=None, **{**TINY, "restarts": 1, "max_steps": 3})
    assert (target / "result.json").is_file() and out.out_dir == target


@pytest.mark.slow
def test_interrupt_leaves_an_interrupted_folder(video, tmp_path):
    def stop(info):
        if info.run == 1 and info.step == 4:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        run_job(video, tmp_path / "i", eq=EQ, log=None, callback=stop, observe="any", **TINY)
    folder = tmp_path / "i"
    report = json.loads((folder / "result.json").read_text())
    assert report["status"] == "interrupted" and report["stage"] == "training" and "interrupted" in report["error"]
    # restarts train together: the interrupt stops both where the trainer last looked (every 10 steps)
    assert [r["status"] for r in report["runs"]] == ["interrupted", "interrupted"]
    assert [r["steps"] for r in report["runs"]] == [10, 10]
    # the estimate is there, flagged as coming from unfinished training
    finals = [r["final"]["gamma"] for r in report["runs"]]
    assert min(finals) - 1e-9 <= report["parameters"]["gamma"]["value"] <= max(finals) + 1e-9
    # and never trusted: the interruption is its verdict's reason
    gamma = report["parameters"]["gamma"]
    assert gamma["verdict"] == "ambiguous" and "interrupted" in gamma["verdict_reason"]
    from fitode.train.result import FitResult
    assert len(FitResult.load(folder / "fit.json").runs[1].history.loss) == 10
    assert {"frames.png", "params.png", "loss.png", "latent.png"} <= {p.name for p in folder.iterdir()}


def test_interrupt_before_any_estimate_keeps_the_history(video, tmp_path):
    def stop(info):
        if info.run == 0 and info.step == 3:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        run_job(video, tmp_path / "i", eq=EQ, log=None, callback=stop, observe="any", **TINY)
    folder = tmp_path / "i"
    report = json.loads((folder / "result.json").read_text())
    assert report["status"] == "interrupted" and report["input"]["sha256"]
    assert report["runs"][0]["steps"] == 10
    # the trainer may hand back the interrupted run (fit.json) or nothing (history.json from the steps seen)
    name = "fit.json" if (folder / "fit.json").exists() else "history.json"
    history = json.loads((folder / name).read_text())
    assert len(history["runs"][0]["history"]["loss"]) == 10
    assert {"frames.png", "params.png", "loss.png"} <= {p.name for p in folder.iterdir()}


def test_every_run_failing_leaves_a_failed_folder(video, tmp_path):
    with pytest.raises(FitodeError, match="every run failed"):
        run_job(video, tmp_path / "f", eq="I' = gamma*I^3", init={"gamma": 1e6}, log=None, **{**TINY, "restarts": 1})
    report = json.loads((tmp_path / "f" / "result.json").read_text())
    assert report["status"] == "failed" and "every run failed" in report["error"]
    assert report["parameters"] == {}


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT semantics")
def test_real_ctrl_c(video, tmp_path):
    """SIGINT to a running `fitode`: status 130, and the folder says interrupted."""
    out = tmp_path / "ctrl-c"
    p = subprocess.Popen([sys.executable, "-m", "fitode", str(video), "--eq", EQ, "--out", str(out), "--quiet",
                          "--max-steps", "100000", "--min-steps", "100000", "--window", "8", "--stride", "1",
                          "--restarts", "1", "--observe", "any"],  # one restart: no search for data starts
                         # before training; an encoder trained (a measured light is fitted at once)
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        deadline = time.time() + 120
        while not (out / "frames.png").exists() and time.time() < deadline and p.poll() is None:
            time.sleep(0.2)
        time.sleep(5.0)  # well into the training loop, even on a busy machine
        assert p.poll() is None, p.communicate()
        os.kill(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130, (p.returncode, err)
    assert err.strip().splitlines()[-1] == "fitode: interrupted"
    report = json.loads((out / "result.json").read_text())
    assert report["status"] == "interrupted"
    assert report["runs"] and report["runs"][0]["steps"] > 0


def test_times_are_video_times_after_start(video, tmp_path):
    """With --start 1, frame 0 is at t = 1 s: latent.png, result.json and --calibrate all use video time."""
    out = run_job(video, tmp_path / "s", eq=EQ, start=1.0, calibrate="I(1)=1; I(3.5)=0.3", log=None,
                    **{**TINY, "restarts": 1, "max_steps": 3})
    traj = out.report["trajectory"]
    assert traj["time"][0] == pytest.approx(1.0) and out.report["input"]["first_frame_time_s"] == pytest.approx(1.0)
    from fitode.calibrate import local_value  # the points are read from a local quadratic of the latent
    assert local_value(np.array(traj["time"]), np.array(traj["latent"])[:, 0], 1.0) == pytest.approx(1.0, abs=1e-6)
    with pytest.raises(FitodeError, match="outside the clip"):
        run_job(video, tmp_path / "s2", eq=EQ, start=1.0, calibrate="I(0.5)=1; I(3.5)=0.3", log=None, **TINY)
    assert not (tmp_path / "s2").exists()
