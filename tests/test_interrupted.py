"""Ctrl-C and SIGTERM to a real `fitode VIDEO` in each stage of a fit: nothing finished is lost.

Each process is held at its stage by FITODE_HOLD_AT (fitode.interrupted), so the signal lands
inside that stage on any machine, however loaded; the four runs go side by side.
"""
from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fitode.examples.make_example import decay_values, render_glow, write_mp4

EQ = "I' = -gamma*I"
# (stage, signal, whether the estimate is kept, what its verdict's reason says was left undone)
CASES = [("training", signal.SIGTERM, "the 95% interval and the checks behind the verdict"),
         ("intervals", signal.SIGINT, "the 95% interval and the checks behind the verdict"),
         ("assessment", signal.SIGTERM, "the checks behind the verdict"),
         ("pictures", signal.SIGINT, None)]


@pytest.mark.slow  # four real fits of a 40-frame, 16x16 clip, run side by side
def test_a_signal_in_any_stage_keeps_the_estimates(tmp_path):
    video = write_mp4(tmp_path / "glow.mp4", render_glow(decay_values(40, 10.0, 0.5), size=16), 10.0)
    procs = {}
    for stage, sig, _ in CASES:
        err = (tmp_path / f"{stage}.err").open("w")
        cmd = [sys.executable, "-m", "fitode", str(video), "--eq", EQ, "--restarts", "2", "--max-steps", "10",
               "--window", "8", "--stride", "1", "--out", str(tmp_path / stage)]
        # a Ctrl-C reaches it as from a terminal, even where pytest itself runs with SIGINT ignored (a background job)
        procs[stage] = subprocess.Popen(cmd, env={**os.environ, "FITODE_HOLD_AT": stage}, stdout=subprocess.PIPE,
                                        stderr=err, text=True, cwd=tmp_path,
                                        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 240
    waiting = dict(procs)
    while waiting and time.time() < deadline:
        for stage, p in list(waiting.items()):
            held = f"fitode: holding at {stage}" in (tmp_path / f"{stage}.err").read_text()
            assert held or p.poll() is None, (tmp_path / f"{stage}.err").read_text()
            if held:
                p.send_signal(dict((s, g) for s, g, _ in CASES)[stage])
                del waiting[stage]
        time.sleep(0.1)
    assert not waiting, f"never reached {sorted(waiting)}"
    for stage, sig, undone in CASES:
        p = procs[stage]
        out, _ = p.communicate(timeout=120)
        err = (tmp_path / f"{stage}.err").read_text()
        assert p.returncode == (130 if sig == signal.SIGINT else 128 + signal.SIGTERM), err
        assert "Traceback" not in err, err
        folder = tmp_path / stage
        report = json.loads((folder / "result.json").read_text())
        assert report["status"] == "interrupted" and report["stage"] == stage, (stage, report.get("status"))
        gamma = report["parameters"]["gamma"]
        assert 0.1 < gamma["value"] < 10  # the fit finished before every one of these stages
        rows = list(csv.DictReader((folder / "estimates.csv").open()))
        assert [r["constant"] for r in rows] == ["gamma"] and float(rows[0]["value"]) == gamma["value"]
        if undone is not None:
            assert gamma["verdict"] == "ambiguous" and gamma["verdict_reason"].endswith(f"not made: {undone}")
            assert f"results (interrupted during the {stage})" in out
        if stage in ("assessment", "pictures"):  # the interval was made before
            assert rows[0]["interval_low"] and rows[0]["interval_high"]
        if stage == "pictures":  # a finished assessment is kept
            assert "interrupted" not in gamma["verdict_reason"]
            assert "track.png" not in report["files"] and "estimates.csv" in report["files"]


def test_a_stop_names_what_it_left_undone():
    from fitode.interrupted import STAGES, stop
    from fitode.train.result import Estimate, FitResult
    import numpy as np

    r = FitResult(parameters={"k": Estimate(1.0, 0.0, 1)}, runs=[], selected=[0], best=0, latent=np.zeros((2, 1)),
                  rollout=np.zeros((2, 1)), time=np.zeros(2), train_frames=2, dt=0.1, states=["x"], equation="x' = -k*x",
                  fixed={}, settings={})
    stop(r, "calibration", calibrating=True)
    assert r.meta["stopped"] == {"stage": "calibration",
                                 "undone": ["the calibration", "the 95% interval", "the checks behind the verdict"]}
    assert r.verdicts["k"]["verdict"] == "ambiguous"
    stop(r, "pictures")
    assert r.meta["stopped"]["undone"] == [] and "pictures" in STAGES
