"""fitode.train.steps: a coarse clip's constants settle once the integrator takes enough steps per frame."""
from __future__ import annotations

import numpy as np
import pytest

import fitode
from fitode import synth
from fitode.eqparse import parse
from fitode.train.steps import STEP_SHIFT, settle_substeps
from fitode.train.trajectory import fit_trajectory, long_options

OSC = parse("z'' + g1*z' + g0*z = 0")
G0, G1 = 4.0016, 0.08  # the paper's: omega 2, a light damping


def _path(dt: float, n: int, noise: float = 1e-4, seed: int = 0) -> np.ndarray:
    """The exact damped swing z = e^(-g1 t / 2) cos(2 t), sampled every dt, with a little noise."""
    t = np.arange(n) * dt
    z = np.exp(-G1 / 2 * t) * np.cos(np.sqrt(G0 - G1 ** 2 / 4) * t)
    return (z + np.random.default_rng(seed).normal(0, noise, n))[:, None]


def _fit(x: np.ndarray, dt: float, substeps: int):
    return fit_trajectory(OSC, {}, x, dt, {"g0": 4.0, "g1": 0.079}, substeps=substeps, **long_options(len(x)))


def test_a_coarse_light_swing_needs_more_than_one_step_per_frame():
    x = _path(0.2, 270)  # 16 frames a period, as the paper's motion video
    one = _fit(x, 0.2, 1)
    assert one.values["g1"] < G1 * (1 - 1e-3)  # one RK4 step a frame reads its loss of amplitude as damping
    steps = settle_substeps(OSC, {}, x, 0.2, one, gauge=None, substeps=1)
    assert steps.settled and steps.substeps >= 2
    assert abs(steps.shifts[0]["g1"]) > 1e-3 and abs(steps.shifts[-1]["g1"]) <= STEP_SHIFT * 2
    settled = _fit(x, 0.2, steps.substeps)
    assert settled.values["g1"] == pytest.approx(G1, rel=5e-4)
    assert settled.values["g0"] == pytest.approx(G0, rel=5e-5)
    assert "steps per frame" in steps.reason("rk4")


def test_a_finely_sampled_swing_keeps_one_step():
    x = _path(0.02, 600)
    one = _fit(x, 0.02, 1)
    steps = settle_substeps(OSC, {}, x, 0.02, one, gauge=None, substeps=1)
    assert steps.substeps == 1 and steps.settled and len(steps.shifts) == 1


@pytest.mark.slow
def test_the_paper_motion_video_gives_the_damping_within_a_tenth_of_a_percent(tmp_path):
    video = synth.paper_video("motion", n_frames=200)
    path = synth.write_video(video, tmp_path / "motion.mp4")
    result = fitode.fit(str(path), eq="z'' + g1*z' + g0*z = 0")
    assert result.settings["substeps"] >= 2 and result.checks["integrator"]["settled"]
    for name, truth in (("g0", G0), ("g1", G1)):
        p = result.parameters[name]
        assert p.value == pytest.approx(truth, rel=1e-3)
        assert p.interval[0] <= truth <= p.interval[1]
        assert result.verdicts[name]["verdict"] == "trusted"


@pytest.mark.slow
def test_the_pass_at_the_settled_step_size_reuses_the_stretch_search(monkeypatch):
    # the paper's coarse motion needs 2 steps a frame: the constants are fitted again at that
    # step, where the law holds is not searched again
    from fitode.train import trainer
    calls = []
    search = trainer._stretch
    monkeypatch.setattr(trainer, "_stretch", lambda *a, **k: calls.append(1) or search(*a, **k))
    video = synth.paper_video("motion", n_frames=120)
    result = fitode.fit(video.frames, video.dt, eq="z'' + g1*z' + g0*z = 0", restarts=2, progress=False)
    assert result.meta.get("direct") and result.settings["substeps"] >= 2
    assert len(calls) == 1
    assert result.meta["stretch"]["source"] == "found" and result.meta["stretch"]["end_frame"] == 120
