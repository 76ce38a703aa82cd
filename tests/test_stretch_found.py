"""The stretch of a one-way clip found without --start/--end (issue 22): the tracker follows a
ball that falls out of a hand across the view (fitode.video.track.follow), the path counts as
one way where one run of it covers most of its travel (tracking.runs_one_way), the stretch finder
takes the fall between the hand and the floor even where a camera bends it by more than its noise
(train/stretch.py), and a clean clip that one trajectory explains is not cut."""
from __future__ import annotations

import numpy as np
import pytest
import torch

import fitode
from fitode.train.observe.tracking import runs_one_way
from fitode.train.stretch import at_rest, find_stretch, noise_level, one_way_runs, rest_window, settled_ends
from fitode.video.track import follow

from test_observe_plugins import FAST, PixelTracker, _frames

DT = 1 / 60


def _drop_candidates(n=120, release=50, land=78):
    """Each frame's candidates (x, y, area, mass), strongest first, as the real drop's were: a
    static change at the floor (a ghost) outweighs everything but the falling ball, and is gone
    in the fall's first frames; the hand holds the ball high up, lets it go at frame `release` and
    stays; the ball falls 1.0 px/frame^2 (a step 28 px by the end, against a clip whose strongest
    change barely moves), outweighs the ghost for the first half of its fall and not the second,
    and rests on the floor from `land`, beside the ghost; from frame n - 10 a person walks in and
    the floor's change is gone. The ghost is 30 pixels across: the object's own motion per frame
    is a quarter of that, and the fall's last steps nearly four times it."""
    rng = np.random.default_rng(0)
    ghost, hand = (80.0, 410.0), (20.0, 10.0)
    found, ball = {}, {}
    for t in range(n):
        jitter = rng.normal(0, 0.3, 4)
        h = (hand[0] + jitter[0], hand[1] + jitter[1], 40.0)
        if t < release:
            ball[t] = (h[0] + 15, h[1] + 5)
            found[t] = [(*ghost, 900.0, 50.0), (*ball[t], 30.0, 10.0), (h[0], h[1], 40.0, 8.0)]
        elif t < land:
            s = t - release
            ball[t] = (35.0 + 0.5 * s, 15.0 + 0.5 * s ** 2)
            fall = (*ball[t], 30.0, 12.0 if s < (land - release) // 2 else 6.0)
            found[t] = sorted(([(*ghost, 900.0, 11.0)] if s >= 8 else []) + [fall, (h[0], h[1], 40.0, 9.0)],
                              key=lambda c: -c[3])
        elif t < n - 10:
            ball[t] = (49.0 + jitter[2], 407.0 + jitter[3])  # where the fall ends
            found[t] = [(*ghost, 900.0, 50.0), (*ball[t], 30.0, 10.0), (h[0], h[1], 40.0, 9.0)]
        else:
            ball[t] = (49.0, 407.0)
            found[t] = [(30.0 + 5 * (t - n + 10), 200.0, 400.0, 90.0), (h[0], h[1], 40.0, 9.0)]
    return found, ball


def test_the_path_follows_a_ball_out_of_the_hand_rather_than_a_stronger_static_change():
    found, ball = _drop_candidates()
    path, = follow(found, len(found), 1)
    xy = {t: found[t][j][:2] for t, j in path.items()}
    # the whole fall, and the hand that held the ball before it (not the stronger ghost)
    for t in range(50, 78):
        assert np.hypot(*np.subtract(xy[t], ball[t])) < 1e-9, t
    assert all(xy[t][1] < 50 for t in range(0, 50))


def test_a_path_held_dropped_and_bounced_runs_one_way_a_swing_does_not():
    t = np.arange(300) * DT
    hold = np.where(t < 1, 0.0, 0.5 * 9.81 * np.clip(t - 1, 0, None) ** 2)
    floor = 0.5 * 9.81 * 0.6 ** 2
    bounce = np.where(t < 1.6, hold, floor - 0.2 * floor * np.sin(np.pi * np.clip((t - 1.6) / 0.8, 0, 1)))
    path = bounce + np.random.default_rng(1).normal(0, 0.002, len(t))
    assert runs_one_way(torch.from_numpy(path))  # the rank correlation alone says no: a hand, a bounce, a rest
    runs = one_way_runs(path)
    assert runs[1][2] > 0.95 and runs[-1][2] == pytest.approx(0.2, abs=0.03)
    swing = np.sin(2 * np.pi * t / 1.3)
    damped = np.exp(-0.4 * t) * swing
    assert not runs_one_way(torch.from_numpy(swing)) and not runs_one_way(torch.from_numpy(damped))


def _fall_between_rests(noise=0.0004, bend=0.08, seed=0):
    """A hand that holds a ball (it wobbles), the ball's fall of 0.6 s read by a camera at an angle
    (the path stretched towards its end by `bend`: a misfit far above the noise for one parabola),
    and the ball on the floor to the end; frames of 1/60 s. Returns t, x, release, landing."""
    rng = np.random.default_rng(seed)
    t = np.arange(160) * DT
    release, land = 60, 96
    s = np.clip(t - t[release], 0.0, t[land] - t[release])
    fall = 0.5 * 9.81 * s ** 2
    depth = fall[land]
    seen = fall * (1 + bend * fall / depth)
    hand = 0.01 * np.sin(2 * np.pi * t / 0.7)  # a hand is never quite still
    x = np.where(t < t[release], hand, seen) + rng.normal(0, noise, len(t))
    x[land:] = seen[land] + rng.normal(0, noise, len(t) - land)
    return t, x, release, land


def _parabola_fit(t, x):
    def fit(a, b):
        c = np.polyfit(t[a:b], x[a:b], 2)
        return (np.polyval(c, t[a:b]) - x[a:b])[:, None]
    return fit


def test_the_fall_between_a_hand_and_the_floor_is_the_stretch_though_a_camera_bends_it():
    t, x, release, land = _fall_between_rests()
    misfit = float(np.sqrt(np.mean(_parabola_fit(t, x)(release, land) ** 2)))
    assert misfit > 10 * 0.0004  # one parabola misses the whole fall by far more than the noise
    found = find_stretch(x[:, None], DT, _parabola_fit(t, x))
    assert release - 3 <= found.start <= release + 3 and land - 4 <= found.end <= land + 1, found
    # the evenly spread seeds alone (no main seed) took a piece of it, or the floor
    assert found.end - found.start >= 0.85 * (land - release)


def test_a_clean_fall_from_rest_to_the_clip_end_is_not_cut():
    t = np.arange(200) * DT
    x = 0.5 * 9.81 * np.clip(t - 1.0, 0, None) ** 2 + np.random.default_rng(2).normal(0, 0.0005, len(t))
    found = find_stretch(x[:, None], DT, _parabola_fit(t, x))
    assert found.start <= 60 and found.end == len(t)


@pytest.mark.slow
def test_a_clean_drain_that_never_rests_is_not_cut():
    # one trajectory of h' = -k*sqrt(h) over the whole clip, measured in metres: the stretch is the
    # clip (a search of a path that never rests cut a clean 8 s path of two oscillators to 1.25 s)
    k, dt = 0.1, 0.05
    t = np.arange(160) * dt
    h = (1.0 - k * t / 2) ** 2 + 1e-4 * np.random.default_rng(3).standard_normal(len(t))
    res = fitode.fit(_frames(h), dt, eq="h' = -k*sqrt(h)", observe=PixelTracker(("h",), physical=True), **FAST)
    stretch = res.meta["stretch"]
    assert (stretch["start_frame"], stretch["end_frame"]) == (0, len(t)), stretch
    assert res.values["k"] == pytest.approx(k, rel=0.01)


def _landing(drift=0.02, seed=0):
    """A throw's height filmed at 240 fps, in pixels: held 80 frames, 48 frames of flight, at rest
    80 frames where it lands; read to 0.006 px from frame to frame, and at rest wandering by
    `drift` px either way in a codec's slow noise (over some 30 frames)."""
    rng = np.random.default_rng(seed)
    dt = 1 / 240
    t = np.arange(48) * dt
    flight = 2.0 + 250.0 * t - 0.5 * 10400.0 * t ** 2  # lands 1 px under its launch
    x = np.concatenate([np.zeros(80), flight[:-1], np.full(81, flight[-1])])
    frames = np.arange(len(x))
    wander = drift * np.sin(2 * np.pi * frames / 31 + rng.uniform(0, 2 * np.pi))
    return x + 0.006 * rng.standard_normal(len(x)) + np.where(frames >= 127, wander, 0.0), dt


@pytest.mark.parametrize("drift", [0.0, 0.02, 0.05])
def test_a_ball_at_rest_where_it_lands_is_at_rest_though_it_wanders_more_than_its_noise(drift):
    # 0.02 px of wander is 7 spreads of its frame-to-frame noise over a rest window: no rest by
    # REST_SIGMAS alone, and the stretch grew from the flight into 35 frames of it (g 0.13 for 19.2)
    x, dt = _landing(drift)
    rest = at_rest(x[:, None], dt, noise_level(x[:, None]))
    assert rest[:75].all() and rest[135:].all() and not rest[82:125].any()
    found = find_stretch(x[:, None], dt, _parabola_fit(np.arange(len(x)) * dt, x))
    assert 76 <= found.start <= 81 and 125 <= found.end <= 129, found


def test_a_motion_that_slows_smoothly_has_no_settled_end():
    # a drain's level and a decay slow down as they end: as slow just before their last frames
    # as in them, so no end of theirs is a rest, however little it moves
    t = np.arange(600) * 0.05
    drain = (1.0 - 0.06 * t / 2) ** 2 + 1e-5 * np.random.default_rng(1).standard_normal(len(t))
    decay = np.exp(-0.25 * t) + 1e-5 * np.random.default_rng(2).standard_normal(len(t))
    for x in (drain, decay):
        assert settled_ends(x[:, None], rest_window(0.05)) == (0, 0)


def test_a_stretch_that_runs_past_a_stop_by_friction_ends_where_its_trajectory_turns():
    # x'' = -a turns back where the speed reaches zero; the thing at rest does not: the frames past the
    # turn are left out. A decay that settles into its rest does not turn back, and is kept whole.
    from fitode.train.stretch import _turned

    dt, a = 1 / 60, 546.0
    t = np.arange(120) * dt
    stop = 80
    x = np.where(t < stop * dt, 0.5 * a * (stop * dt - t) ** 2, 0.0)
    x = (-x + np.random.default_rng(0).normal(0, 0.05, len(t)))[:, None]

    def parabola(lo, hi):
        s = np.arange(hi - lo)
        return (np.polyval(np.polyfit(s, x[lo:hi, 0], 2), s) - x[lo:hi, 0])[:, None]

    assert _turned(x, parabola, 10, stop + 5, stop, 12, 0.05) in (stop, stop + 1)
    assert _turned(x, parabola, 10, stop + 1, stop, 12, 0.05) == stop + 1  # too close to the turn to tell
    decay = (100 * np.exp(-3 * t) + np.random.default_rng(1).normal(0, 0.05, len(t)))[:, None]

    def exponential(lo, hi):
        s = t[lo:hi]
        k, c = np.polyfit(s, np.log(np.maximum(decay[lo:hi, 0], 1e-3)), 1)
        return (np.exp(c + k * s) - decay[lo:hi, 0])[:, None]

    assert _turned(decay, exponential, 0, 120, 100, 12, 0.05) == 120
