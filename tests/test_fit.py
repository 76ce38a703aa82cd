"""fitode.fit end to end on small generated videos (the trainer issue's done-when checks)."""
import math

import numpy as np
import pytest

import fitode
from fitode import synth
from fitode.train.result import FitResult
from fitode.eqparse import parse
from fitode.errors import TrainingError

pytestmark = pytest.mark.slow  # end-to-end fits: `pytest -m 'not slow'` skips them

G0, G1 = 4.0016, 0.08


@pytest.fixture(scope="module")
def intensity():
    return synth.paper_video("intensity", size=32, n_frames=120)


@pytest.fixture(scope="module")
def oscillator_fit(intensity):
    # far from the truth: g0 more than twice, g1 twelve times too large
    return fitode.fit(intensity.frames, intensity.dt, system="damped_oscillator", init={"g0": 9.0, "g1": 1.0},
                      restarts=1, max_steps=350, progress=False)


def test_recovers_damped_oscillator_from_far_init(oscillator_fit):
    est = oscillator_fit.values
    assert abs(est["g0"] - G0) / G0 < 0.02, est
    assert abs(est["g1"] - G1) / G1 < 0.25, est
    run = oscillator_fit.runs[0]
    assert run.status == "ok" and run.init == {"g0": 9.0, "g1": 1.0}
    assert len(run.history.loss) == run.steps


def test_latent_follows_the_true_state(oscillator_fit, intensity):
    # the encoder sees the state only up to scale and offset: compare by correlation
    r = np.corrcoef(oscillator_fit.latent[:, 0], intensity.latent[:, 0])[0, 1]
    assert abs(r) > 0.99


def test_without_kl_the_encoder_collapses(intensity):
    res = fitode.fit(intensity.frames, intensity.dt, system="damped_oscillator", init={"g0": 9.0, "g1": 1.0},
                     restarts=1, max_steps=300, use_kl=False, progress=False)
    with_kl = fitode.fit(intensity.frames, intensity.dt, system="damped_oscillator",
                         init={"g0": 9.0, "g1": 1.0}, restarts=1, max_steps=30, progress=False)
    assert res.latent.std() < 0.02 * with_kl.latent.std(), (res.latent.std(), with_kl.latent.std())


def test_result_round_trips_through_json_and_extrapolates(oscillator_fit, tmp_path):
    path = oscillator_fit.save_json(tmp_path / "fit.json")
    back = FitResult.load(path)
    assert back.values == pytest.approx(oscillator_fit.values)
    assert np.allclose(back.latent, oscillator_fit.latent)
    # predict() rebuilds the physics block from the saved equation and continues past the video
    n = len(back.latent)
    pred = back.predict(n + 50)
    assert pred.shape == (n + 50, 1)
    assert np.allclose(pred[:n], oscillator_fit.rollout, rtol=1e-3, atol=1e-3)
    # from a later start the prediction tracks the encoded latent for a while
    late = back.predict(20, start=60)
    assert np.sqrt(np.mean((late[:, 0] - back.latent[60:80, 0]) ** 2)) < 0.1 * back.latent.std()


def test_a_restart_that_turns_nan_is_reported_failed_and_left_out():
    # sqrt(c) is NaN for negative c: restart 0 starts at the user's c = -1 and fails at its first
    # step; restart 1 starts from the data search and goes on untouched in the same batch
    frames = synth.paper_video("intensity", size=16, n_frames=60).frames
    eq = "I' = -gamma*I + 1e-6*sqrt(c)"
    res = fitode.fit(frames, 0.2, eq=eq, restarts=2, max_steps=30, init={"c": -1.0}, progress=False)
    bad, ok = res.runs
    assert ok.status == "ok" and bad.status == "failed"
    assert "sqrt(c)" in bad.error and bad.stop_reason == "non-finite"
    assert ok.steps == 30 and len(ok.history) == 30
    assert res.selected == [1] and res.failed == [0]
    assert math.isfinite(res.values["gamma"])
    with pytest.raises(TrainingError, match="every run failed"):
        fitode.fit(frames, 0.2, eq=eq, restarts=1, max_steps=30, init={"c": -1.0}, progress=False)
