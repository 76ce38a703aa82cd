"""SIGTERM (what `kill`, schedulers and containers send) takes the same path as Ctrl-C.

`fitode batch` stops its workers at once and leaves a consistent summary; `fitode VIDEO` leaves
its run folder marked interrupted. Both are real processes signalled from here.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from test_batch import EQ, RUNNER, _calls, _csv, _summary, _video

TESTS = Path(__file__).parent


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}


def _gone_within(pids: list[int], seconds: float) -> list[int]:
    """The pids still alive after `seconds`."""
    deadline = time.time() + seconds
    alive = list(pids)
    while alive and time.time() < deadline:
        alive = [p for p in alive if _alive(p)]
        time.sleep(0.05)
    return [p for p in alive if _alive(p)]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (exited, not yet reaped by its parent) counts as gone
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.slow  # a real SIGTERM to a driver process whose workers must be running
def test_sigterm_stops_batch_workers_and_leaves_the_summary_consistent(tmp_path):
    _video(tmp_path, "quick.json", gamma=0.5)
    for i in range(3):
        _video(tmp_path, f"slow{i}.json", gamma=0.5, sleep=60)
    m = _csv(tmp_path, [f"quick.json,A,{EQ},"] + [f"slow{i}.json,A,{EQ}," for i in range(3)])
    out = tmp_path / "out"
    # the real command line, with the stand-in job so that the workers just sleep
    script = ("import sys, fitode.cli, fitode.batch.runner as r\n"
              f"r.run_batch.__kwdefaults__['runner'] = {RUNNER!r}\n"
              "if __name__ == '__main__':\n"
              f"    sys.exit(fitode.cli.main(['batch', {str(m)!r}, '--out', {str(out)!r}, '--workers', '2', "
              "'--quiet']))\n")
    proc = subprocess.Popen([sys.executable, "-c", script], env=_env(), stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and len(_calls(out)) < 3:  # quick is done and two slow ones are running
        time.sleep(0.1)
    assert len(_calls(out)) == 3
    worker_pids = [int(line.split()[1]) for line in (out / "calls.log").read_text().splitlines()]
    t0 = time.time()
    proc.send_signal(signal.SIGTERM)
    assert _gone_within(worker_pids, 2.0) == [], "workers outlived SIGTERM to the driver by 2 s"
    _, err = proc.communicate(timeout=30)
    assert time.time() - t0 < 15
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert err.strip().splitlines()[-1] == "fitode: terminated" and "Traceback" not in err, err
    s = _summary(out)
    assert s["interrupted"] is True
    assert [j["status"] for j in s["jobs"]] == ["complete", "pending", "pending", "pending"]


def test_sigterm_in_process_restores_the_previous_handler():
    from fitode.cli import main

    before = signal.getsignal(signal.SIGTERM)
    assert main(["check", "--list"]) == 0
    assert signal.getsignal(signal.SIGTERM) is before


@pytest.mark.slow  # a real fit, signalled while it trains
def test_sigterm_during_a_fit_leaves_the_run_interrupted(tmp_path):
    from fitode.examples.make_example import decay_values, render_glow, write_mp4

    video = write_mp4(tmp_path / "glow.mp4", render_glow(decay_values(60, 10.0, 0.5), size=16), 10.0)
    out = tmp_path / "run"
    # --min-steps: restarts that converge stop early, and this fit must still be training when signalled;
    # one restart: no search for data starts before training, which takes many seconds on a busy machine
    # --observe any: the encoder is trained (auto reads this lamp as a measured light, fitted in a second)
    cmd = [sys.executable, "-m", "fitode", str(video), "--eq", EQ, "--max-steps", "100000", "--min-steps", "100000",
           "--window", "8", "--observe", "any",
           "--stride", "1", "--restarts", "1", "--out", str(out)]
    proc = subprocess.Popen(cmd, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.time() + 120
    # result.json ("running") is written just before training starts
    while time.time() < deadline and proc.poll() is None and not (out / "result.json").exists():
        time.sleep(0.1)
    assert proc.poll() is None, "the run ended before it could be signalled"
    time.sleep(3)  # well inside the training steps
    t0 = time.time()
    proc.send_signal(signal.SIGTERM)
    try:
        text, _ = proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("fitode VIDEO did not stop within 20 s of SIGTERM")
    assert time.time() - t0 < 10, text
    assert proc.returncode != 0, text
    assert "Traceback" not in text, text
    report = json.loads((out / "result.json").read_text())
    assert report["status"] == "interrupted", report.get("status")
