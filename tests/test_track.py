"""Position read along the axes a state's name says (x across; y, h, z up), from the reader's
track: `y'' = -g` reads the height of a throw, `x'' = 0; y'' = -g` both coordinates."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from fitode.eqparse import parse
from fitode.train.observe import PositionObservation, Track, resolve_observation


def _throw(n=60):
    t = np.arange(n) / 30
    return np.column_stack([20 + 200 * t, 200 - 150 * t + 120 * t ** 2])  # mostly across, y down


def _model(eq: str, xy: np.ndarray, observe=None):
    system = parse(eq)
    model = resolve_observation(observe or "position", system, track=Track(xy, 5.0, 1, "generated"))
    return model, model.prepare(torch.zeros(len(xy), 1, 8, 8)).in_order(system.states)


def test_a_state_named_y_reads_the_height_not_the_flight_direction():
    xy = _throw()
    _, prepared = _model("y'' = -g", xy)
    z = prepared.inputs.reshape(-1).numpy()
    assert np.corrcoef(z, -xy[:, 1])[0, 1] > 0.999  # up is minus the image's y
    assert prepared.drawing["states"] == {"y": "y"} and len(prepared.drawing["track"]) == len(xy)
    _, along = _model("s'' = -g", xy)  # a name that says no axis: the line of motion, the horizontal here
    assert abs(np.corrcoef(along.inputs.reshape(-1).numpy(), xy[:, 0])[0, 1]) > 0.95
    assert "line" in along.drawing


def test_two_states_named_for_axes_measure_both_coordinates():
    xy = _throw()
    model, prepared = _model("x'' = 0; y'' = -g", xy)
    assert prepared.states == ("x", "y") and prepared.inputs.shape == (len(xy), 2, 1, 1)
    cols = prepared.inputs[:, :, 0, 0].numpy()
    assert np.corrcoef(cols[:, 0], xy[:, 0])[0, 1] > 0.999 and np.corrcoef(cols[:, 1], -xy[:, 1])[0, 1] > 0.999
    assert not model.applies("perspective")
    per_state, one_each = _model("x'' = 0; y'' = -g", xy, observe="x=position;y=position")
    np.testing.assert_allclose(one_each.inputs.numpy(), prepared.inputs.numpy(), atol=1e-6)
    assert isinstance(model, PositionObservation)


def test_strays_of_an_oscillation_are_mended_and_a_clean_swing_is_left_alone():
    from fitode.train.observe import mend_strays

    rng = np.random.default_rng(0)
    t = np.arange(300) / 30
    clean = np.column_stack([100 + 40 * np.sin(2 * np.pi * t / 1.3), 100 + 3 * np.cos(2 * np.pi * t / 1.3)])
    clean += rng.normal(0, 0.3, clean.shape)
    bad = clean.copy()
    strays = [50, 51, 120, 200, 201, 202]
    bad[strays] += [60, -30]  # the centroid jumped to something else for a frame or three
    mended, count = mend_strays(bad)
    assert set(strays) <= set(np.flatnonzero(np.linalg.norm(mended - bad, axis=1) > 0)) and count <= 10
    assert np.abs(mended - clean).max() < 5  # from 67 pixels off
    assert mend_strays(clean)[1] == 0


def test_a_ball_bouncing_at_30_fps_is_no_stray_and_a_hand_for_two_frames_is():
    # a ball dropped from a hand, filmed at 30 fps: its path bends by g dt^2 (10 px) from frame to
    # frame and turns round at the floor; the line through two frames misses the next by that
    # much, so a real ball's first flight was read from its neighbours as a straight line
    from fitode.synth.scenes import _flights
    from fitode.train.observe import mend_strays

    t = np.arange(150) / 30 - 1.0
    y = 900 * _flights(1.0, 0.0, 9.81, 0.75, 5, t)[0] + np.random.default_rng(1).normal(0, 0.3, len(t))
    mended, count = mend_strays(y)
    assert count == 0 and np.array_equal(mended, y)
    for k in (30, 50, 70):  # the centroid on a hand at the edge for two frames, at the top of a flight
        bad = y.copy()
        bad[[k, k + 1]] = [600.0, 602.0]
        mended, count = mend_strays(bad)
        assert count == 2 and np.abs(mended[[k, k + 1]] - y[[k, k + 1]]).max() < 15


def test_a_named_axis_is_read_even_where_it_barely_moves_and_the_line_of_motion_is_suggested():
    t = np.arange(90) / 30
    bounce = np.column_stack([100 + 0.5 * np.sin(7 * t), 120 + 30 * np.cos(7 * t)])  # up and down, named x
    _, prepared = _model("x'' = -k*x", bounce)
    assert np.corrcoef(prepared.inputs.reshape(-1).numpy(), bounce[:, 0])[0, 1] > 0.99  # across, as named
    assert "barely moves" in prepared.caution and "name the state s" in prepared.caution
    _, line = _model("s'' = -k*s", bounce)  # a name that says no axis reads the line of motion
    assert abs(np.corrcoef(line.inputs.reshape(-1).numpy(), bounce[:, 1])[0, 1]) > 0.99 and line.caution is None


def test_a_flat_throw_named_y_reads_its_height():
    t = np.arange(60) / 240  # a 25-degree throw's flight: 225 pixels across, 19 up (image y down)
    throw = np.column_stack([50 + 900 * t, 200 - 300 * t + 0.5 * 2400 * t ** 2])
    assert throw[:, 1].std() < 0.3 * throw[:, 0].std()  # the height carries under 30% of the motion
    _, prepared = _model("y'' = -g", throw)
    assert np.corrcoef(prepared.inputs.reshape(-1).numpy(), -throw[:, 1])[0, 1] > 0.999  # up, not the flight


@pytest.mark.slow
def test_a_ball_three_pixels_across_in_a_codecs_noise_is_tracked_within_half_a_pixel(tmp_path):
    """A 240 fps throw at 320x240 (the ball 1.4 px in radius, noise 2.65, written as mp4 and read
    back as the pipeline reads it): the blocks the change is shrunk to locate it carry the codec's
    correlated noise; at the level 4 / 4 noise levels they joined into wide faint regions that
    outweighed the ball, and the track jumped to them (15 px RMS, up to 126 px: g came out of the
    shrunk frames' centroids, -12% +-16%)."""
    from fitode import synth
    from fitode.pipeline import read_clip

    v = synth.scene("throw", 11.1, fps=240, size=(240, 320), noise=2.65, seed=1, angle=46, range=2.0,
                    rest_before=0.1, rest_after=0.1)
    ph = v.meta["physical"]
    clip, _ = read_clip(synth.write_video(v, tmp_path / "throw.mp4"))
    assert clip.stride == 1 and "switches between moving things 0 times" in clip.track.note
    flight = np.arange(ph["flight_start_frame"], ph["flight_end_frame"])
    truth = np.column_stack([np.asarray(ph["x"])[flight], v.latent[flight, 0], np.ones(len(flight))])
    xy = clip.track.filled()[flight]
    off = xy - truth @ np.linalg.lstsq(truth, xy, rcond=None)[0]  # the scene's metres to its pixels
    assert np.sqrt((off ** 2).sum(axis=1).mean()) < 0.4 and np.abs(off).max() < 1.0


def _cover(lo: float, hi: float, n: int) -> np.ndarray:
    """Each pixel's covered share of [lo, hi) along an axis of n pixels."""
    e = np.arange(n + 1, dtype=float)
    return np.clip(np.minimum(e[1:], hi) - np.maximum(e[:-1], lo), 0.0, 1.0)


def test_a_block_resting_a_quarter_of_the_clip_leaves_no_faint_ghost_under_its_track():
    """A dark block rests 70 of 240 frames at its start, slides 200 px and rests again: in the
    median static scene its start place is 2 gray levels darker (under a pixel's 4 noise levels of
    8, so the rebuilt scene was not taken there), which pulled the change-weighted centroid by up to
    0.11 px as the block left it (a generated block's first half of its slide read -1.6%). The
    reader's track is now the one the true static scene gives, within two hundredths of a pixel
    (0.012 px here)."""
    from fitode.video import track as T

    rng = np.random.default_rng(3)
    n, h, w, rest, slide = 240, 100, 260, 70, 100
    yy, xx = np.mgrid[0:h, 0:w]
    wall = 150 + 2 * np.sin(xx / 9.0) + 2 * np.cos(yy / 7.0 + xx / 23.0)
    k = np.clip(np.arange(n) - rest, 0, slide)
    s = 200.0 * (k / slide) ** 2
    frames = np.empty((n, h, w), np.uint8)
    for t in range(n):
        block = np.outer(_cover(40.3, 60.3, h), _cover(20.0 + s[t], 46.0 + s[t], w))
        frames[t] = np.clip(wall * (1 - block) + 70 * block + rng.normal(0, 2.0, (h, w)) + 0.5, 0, 255)
    _, median, noise = T.static_scene(frames)
    assert -4 * noise < (median.astype(float) - wall)[40:60, 20:46].mean() < -1.0  # the faint ghost is there
    xy = T.measure(frames)[0]
    true_scene = np.clip(wall + 0.5, 0, 255).astype(np.uint8)
    ideal = np.array([T._candidates(frames[t], true_scene, noise)[0][:2] for t in range(n)])
    moving = slice(rest, rest + slide)
    assert np.abs(xy[moving] - ideal[moving]).max() < 0.02
