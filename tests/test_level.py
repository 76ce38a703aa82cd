"""The level observation (train/observe/level.py): the height of a water line read from the shift
of the rows' profile, and the auto choice of it for a drain."""
from __future__ import annotations

import numpy as np
import pytest
import torch

import fitode
from fitode import synth
from fitode.eqparse import parse
from fitode.measurement import readings
from fitode.train.observe import LevelObservation, PositionObservation, read_level, resolve_observation
from fitode.train.observe.tracking import centroids, line_of_motion


def _drain(seed: int = 3):
    v = synth.scene("torricelli", 0.016, size=(72, 128), duration=3.0, noise=1.0, seed=seed)
    return v, v.as_tensor_frames()


def _misfit(reading: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """The slope of the best affine map from the truth to a reading, and the reading's rms about
    it as a share of its travel."""
    a = np.c_[truth, np.ones_like(truth)]
    coef, *_ = np.linalg.lstsq(a, reading, rcond=None)
    rest = reading - a @ coef
    return float(coef[0]), float(rest.std() / (reading.max() - reading.min()))


def test_the_level_follows_the_water_line_of_a_drain_with_a_ball_floating_on_it():
    v, frames = _drain()
    level = read_level(frames)
    assert level is not None and level.is_level
    slope, misfit = _misfit(level.height.numpy(), v.latent[:, 0])
    # rows up per metre: the scene draws 0.62 of the frame's height for the tank's 0.30 m; the
    # misfit is the frames' noise (0.2 pixels on a 4-pixel travel), with no trend left
    assert slope > 0 and misfit < 0.08
    assert 0.8 < slope / (0.62 * 72 / 0.30) < 1.25
    # the centroid of the change (the position observation's reading) mixes the ball with the band
    _, along = line_of_motion(centroids(frames)[0])
    assert _misfit(along.numpy(), v.latent[:, 0])[1] > 2 * misfit


def test_auto_reads_a_drain_as_a_level_and_leaves_the_lamp_and_other_equations_alone():
    _, frames = _drain(seed=5)
    picked = resolve_observation(None, parse("h' = -k*sqrt(h)"), frames)
    assert isinstance(picked, LevelObservation) and "horizontal edge" in picked.reason
    # a state that names no vertical, or a second-order one, is not a level
    assert not isinstance(resolve_observation(None, parse("q' = -k*sqrt(q)"), frames), LevelObservation)
    assert not isinstance(resolve_observation(None, parse("h'' = -k*h'"), frames), LevelObservation)
    lamp = synth.scene("led", 1.2, size=(48, 64), duration=1.5, seed=1).as_tensor_frames()
    assert not isinstance(resolve_observation(None, parse("h' = -k*h"), lamp), LevelObservation)
    assert resolve_observation("level", parse("h' = -k*sqrt(h)"), frames).reason == "level (as asked)"


def test_the_level_observation_reads_a_unit_column_and_refuses_frames_without_a_water_line():
    _, frames = _drain()
    model = resolve_observation("level", parse("h' = -k*sqrt(h)"), frames)
    prepared = model.prepare(frames)
    column = prepared.inputs.reshape(-1)
    assert prepared.states == ("h",) and abs(float(column.std()) - 1) < 1e-3
    assert float(column[0]) > float(column[-1])  # the level drops, read as a height
    assert model.measured and not model.fixes_scale() and model.applies("direct")
    # the record draws the height it read, to which the latent maps back affinely
    (reading,) = readings(prepared.drawing, column[:, None].numpy(), column[:, None].numpy(), ["h"])
    assert "water line" in reading.label and np.allclose(reading.fitted, reading.measured, atol=1e-4)
    lamp = synth.scene("led", 1.2, size=(48, 64), duration=1.5, seed=1).as_tensor_frames()
    still = resolve_observation("level", parse("h' = -k*h"), lamp)
    with pytest.raises(fitode.ConfigError, match="no water line"):
        still.prepare(lamp)
    assert not isinstance(resolve_observation(None, parse("h' = -k*sqrt(h)"), frames), PositionObservation)


def test_a_level_is_read_again_at_the_sources_rows_and_reads_finer_there(tmp_path):
    from fitode import api
    from fitode.pipeline import ReadOptions, level_in_detail, read_clip
    v = synth.scene("torricelli", 0.013, size=(135, 240), duration=4.0, noise=1.0, seed=5)
    path = synth.write_video(v, tmp_path / "drain.mp4")
    req = api.requests(system="torricelli")[0]
    clip, t0 = read_clip(path)
    plan = api.plan(req, api.as_frames(clip.frames), clip.dt, track=clip.track)
    assert isinstance(plan.observation, LevelObservation) and clip.frames.shape[-2] == 64
    again, t1, replanned = level_in_detail(path, ReadOptions(), req, clip, t0, plan)
    assert tuple(again.frames.shape[-2:]) == tuple(clip.source_size) and clip.source_size[0] > 130 and t1 == t0 and len(again.frames) == len(clip.frames)
    assert replanned.observation is plan.observation
    truth = v.latent[::clip.stride, 0][: len(clip.frames)]
    shrunk = _misfit(read_level(api.as_frames(clip.frames)).height.numpy(), truth)[1]
    full = _misfit(read_level(api.as_frames(again.frames)).height.numpy(), truth)[1]
    assert full < shrunk  # rms about the truth, a share of the travel: 2.0% at 134 rows, 2.3% at 64
    # frames the user sized are theirs
    given, _ = read_clip(path, ReadOptions(size="128x72"))
    same = level_in_detail(path, ReadOptions(size="128x72"), req, given, t0, plan)[0]
    assert same is given


def test_a_drain_whose_zero_the_calibration_sets_is_judged_on_its_calibrated_path(tmp_path):
    """A slow drain (a level that falls 11% in 4.5 s) read in pixels with its zero free: the
    restarts end at one loss with k 17% apart, each with a zero of its own. The two calibration
    points set the zero; the fit of the calibrated path is the estimate, and its interval comes
    from that path (+-6.8%, most of it the points' readings), not from the restarts' spread
    (+-30%, "the restarts it comes from disagree", before). The points are read on the trajectory
    fitted to every frame: read on the frames at each point (a local quadratic of them), whose
    level errs slowly, k came out -1.8%; and their share of the interval is how far that
    trajectory moves at them with the path's residuals."""
    v = synth.scene("torricelli", 0.013, size=(180, 320), duration=4.5, noise=1.0, seed=1)
    path = synth.write_video(v, tmp_path / "drain.mp4")
    h = v.latent[:, 0]
    res = fitode.fit(path, system="torricelli", calibrate=f"h(0)={h[0]:.9f}; h({(len(h) - 1) * v.dt:.6f})={h[-1]:.9f}",
                     progress=False)
    kept = [run.value("k") for run in res.runs if run.index in res.selected]
    assert max(kept) / min(kept) > 1.05  # the case: apart in the path's own gauge
    k = res.parameters["k"]
    assert res.calibration["gauge_fixed"] == ["k"] and k.n_runs == 1 and k.std == 0.0
    assert [p["read_on"] for p in res.calibration["points"]] == ["the fitted trajectory"] * 2
    assert k.value == pytest.approx(0.013, rel=0.005)
    low, high = k.interval
    # the points' share: what the fitted trajectory's moves there add to the constant's own moves
    # over the same resampled paths (+-3.3% in all); how far the frames at them scatter gave +-6.9%,
    # and the trajectory's moves added apart from the constant's +-4.4%
    assert low <= 0.013 <= high and high - low < 0.08 * k.value
    assert "restarts" not in res.verdicts["k"]["reason"]
    assert "one fit of the measured path as calibrated" in res.summary()
