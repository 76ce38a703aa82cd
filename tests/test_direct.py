"""A measured path fitted directly (train/direct.py), segments of one trajectory
(trajectory.py), and the stretch one trajectory explains (train/stretch.py)."""
from __future__ import annotations

import numpy as np
import pytest

from fitode.eqparse import parse
from fitode.train.stretch import at_rest, find_stretch, noise_level
from fitode.train.trajectory import fit_trajectory, long_options

from test_trajectory import _damped

DT = 1 / 240


def _rest_slide_rest(n=600, a=885.0, t0=0.5, t1=1.6, after: str = "rest", noise=0.3, seed=0):
    t = np.arange(n) * DT
    moving = a / 2 * (t - t0) ** 2
    end = a / 2 * (t1 - t0) ** 2
    later = end if after == "rest" else end - 300.0 * (t - t1)  # it rests, or moves on at another law
    x = np.where(t < t0, 0.0, np.where(t < t1, moving, later))
    return t, x + np.random.default_rng(seed).normal(0.0, noise, n)


def _parabola_fit(t, x):
    def fit(a, b):
        c = np.polyfit(t[a:b], x[a:b], 2)
        return (np.polyval(c, t[a:b]) - x[a:b])[:, None]
    return fit


@pytest.mark.parametrize("after", ["rest", "moves on"])
def test_the_stretch_of_a_slide_between_rests_is_found(after):
    t, x = _rest_slide_rest(after=after)
    found = find_stretch(x[:, None], DT, _parabola_fit(t, x))
    # the slide runs from 0.5 s (frame 120) to 1.6 s (frame 384): the stretch keeps to it within a
    # few frames of rest (which a parabola through its vertex also explains)
    assert 95 <= found.start <= 125 and 380 <= found.end <= 390
    c = np.polyfit(t[found.start:found.end], x[found.start:found.end], 2)
    assert 2 * c[0] == pytest.approx(885.0, rel=0.01)
    assert ("stops" in found.why_end) == (after == "rest")
    assert "starts" in found.why_start
    d = found.to_dict(DT)
    assert d["source"] == "found" and d["start_s"] == pytest.approx(found.start * DT)


def test_one_trajectory_everywhere_is_the_whole_path():
    t = np.arange(400) * DT
    x = 300 * t ** 2 + np.random.default_rng(1).normal(0, 0.2, 400)
    found = find_stretch(x[:, None], DT, _parabola_fit(t, x))
    assert (found.start, found.end) == (0, 400)
    assert "first frame" in found.why_start and "last frame" in found.why_end


def test_rest_and_noise_are_read_from_the_path():
    t, x = _rest_slide_rest(noise=0.5)
    slow = 0.5 * np.random.default_rng(3).normal(size=2000) + np.sin(np.arange(2000) * DT)  # smooth motion + noise
    assert noise_level(slow) == pytest.approx(0.5, rel=0.1)
    rest = at_rest(x, DT, 0.5)
    assert rest[:100].all() and not rest[200:350].any() and rest[-100:].all()


def test_segments_give_the_whole_trajectory_quickly():
    system = parse("x' = v; v' = -w2*x - c*v")
    x = _damped(n=600, noise=0.003)
    whole = fit_trajectory(system, {}, x[:200], 0.05, {"w2": 3.0, "c": 0.5})
    pieces = fit_trajectory(system, {}, x[:200], 0.05, {"w2": 3.0, "c": 0.5}, segments=40, solver="lm")
    assert pieces is not None and pieces.residuals.shape == (200, 2)
    for n in ("w2", "c"):  # the same trajectory: the joins hold it together
        assert pieces.values[n] == pytest.approx(whole.values[n], rel=2e-3)
        assert pieces.errors[n] == pytest.approx(whole.errors[n], rel=0.5)
    long = fit_trajectory(system, {}, x, 0.05, {"w2": 3.0, "c": 0.5}, **long_options(len(x)))
    assert long.values["w2"] == pytest.approx(4.0, rel=0.005) and long.values["c"] == pytest.approx(0.3, rel=0.03)


def _dot_clip(n=90, a=400.0, h=16, w=120, seed=0):
    """A bright dot moving along x as x = 10 + a t^2 / 2 at 240 fps, gray frames (n, h, w)."""
    x = 10 + a / 2 * (np.arange(n) * DT) ** 2
    yy, xx = np.mgrid[:h, :w]
    rng = np.random.default_rng(seed)
    return np.stack([np.exp(-((xx - xi) ** 2 + (yy - h / 2) ** 2) / 8.0) + rng.normal(0, 0.01, (h, w))
                     for xi in x]).astype(np.float32), x


@pytest.mark.slow
def test_a_measured_path_trains_no_encoder(monkeypatch):
    import fitode
    import fitode.train.trainer as trainer

    def refuse(*args, **kwargs):
        raise AssertionError("an encoder was trained for a measured path")
    monkeypatch.setattr(trainer, "train_restarts", refuse)
    frames, x = _dot_clip()
    i, j = 5, 80
    res = fitode.fit(frames, DT, eq="x'' = a", observe="position", restarts=2, stretch=False, progress=False,
                     calibrate=f"x({i * DT})={x[i]}; x({j * DT})={x[j]}")
    assert res.meta["direct"] and res.meta["stretch"]["source"] == "as asked"
    assert res.values["a"] == pytest.approx(400.0, rel=0.02)
    assert len(res.runs) == 2 and res.rollout.shape == res.latent.shape
    assert np.nanmax(np.abs(res.rollout - res.latent)) < 0.05 * np.ptp(res.latent)  # the fitted trajectory


@pytest.mark.slow
def test_a_slide_between_rests_gives_a_without_start_or_end():
    import fitode
    from fitode.synth.scenes import scene

    v = scene("sliding_block", 30, fps=240, size=(90, 160), rest_before=0.3, rest_after=0.3, seed=1)
    s, phys = v.state[:, 0], v.meta["physical"]
    i, j = phys["rest_before_frames"] + 10, len(s) - phys["rest_after_frames"] - 10
    res = fitode.fit(v.frames, v.dt, eq="x'' = a", observe="position", progress=False,
                     calibrate=f"x({i * v.dt:.6f})={s[i]:.6f}; x({j * v.dt:.6f})={s[j]:.6f}")
    assert res.values["a"] == pytest.approx(phys["a"], rel=0.03)
    stretch = res.meta["stretch"]
    assert stretch["source"] == "found" and "starts" in stretch["reason"]
    assert stretch["start_frame"] > phys["rest_before_frames"] // 2
    assert stretch["end_frame"] < len(s) - phys["rest_after_frames"] // 2
    assert res.verdicts["a"]["verdict"] == "trusted"


def test_mended_frames_count_only_on_the_frames_fitted():
    from fitode.train.observe.tracking import mended_caution

    scattered = list(range(40, 100, 3))  # 20 frames inside the motion, apart
    assert "20 of 150 fitted frames" in mended_caution(scattered, 0, 150)
    assert mended_caution(scattered, 100, 250) is None  # none of the fitted frames
    assert mended_caution(scattered, 70, 250) is None  # 10 of 180: few
    # a run at an end of the fitted frames (a ball one blob with the hand that lets it go, the real
    # drop's frames 2-11 of 82) is where the motion meets something, not a stray inside it
    assert mended_caution(list(range(2, 12)), 0, 82) is None
    assert mended_caution(list(range(72, 82)), 0, 82) is None
    assert mended_caution(list(range(2, 12)) + list(range(30, 40)), 0, 82) is not None  # and strays within
    assert "30 of 82" in mended_caution(list(range(30)), 0, 82)  # many: over a quarter


def _slide_with_a_hand(seed: int = 1):
    """The slide between rests of test_a_slide_between_rests_gives_a_without_start_or_end, with a
    bright disk (a hand) flashing at a random place in every other frame of the rest before it:
    those frames' centroids leave the block's path and are read from their neighbours."""
    from fitode.synth.scenes import scene

    v = scene("sliding_block", 30, fps=240, size=(90, 160), rest_before=0.4, rest_after=0.3, seed=seed)
    frames = v.frames.copy()
    yy, xx = np.mgrid[:frames.shape[1], :frames.shape[2]]
    rng = np.random.default_rng(seed)
    for i in range(1, v.meta["physical"]["rest_before_frames"] - 2, 2):
        cy, cx = rng.uniform(20, 70), rng.uniform(110, 150)  # away from the resting block
        frames[i][(yy - cy) ** 2 + (xx - cx) ** 2 < 144] = 255
    return v, frames


@pytest.mark.slow
@pytest.mark.long
def test_a_hand_before_the_slide_leaves_the_fit_trusted():
    import fitode
    from fitode.train.observe.tracking import MENDED_MAX

    v, frames = _slide_with_a_hand()
    s, phys = v.state[:, 0], v.meta["physical"]
    i, j = phys["rest_before_frames"] + 10, len(s) - phys["rest_after_frames"] - 10
    res = fitode.fit(frames, v.dt, eq="x'' = a", observe="position", progress=False,
                     calibrate=f"x({i * v.dt:.6f})={s[i]:.6f}; x({j * v.dt:.6f})={s[j]:.6f}")
    mended = res.meta["measurement"]["mended"]
    assert len(mended) > MENDED_MAX * len(s)  # counted on the whole clip, a caution
    first, last = res.meta["stretch"]["start_frame"], res.meta["stretch"]["end_frame"]
    assert res.meta["stretch"]["source"] == "found" and first > phys["rest_before_frames"] // 2
    assert sum(first <= m < last for m in mended) <= MENDED_MAX * (last - first)
    assert res.values["a"] == pytest.approx(phys["a"], rel=0.03)
    assert res.verdicts["a"]["verdict"] == "trusted", res.checks["findings"]


def test_a_constant_the_windows_drove_onto_its_bound_starts_the_whole_fit_from_the_restarts_value():
    from fitode.eqparse import ParamSpec
    from fitode.train.direct import off_bounds
    from fitode.train.trajectory import TrajectoryFit
    lead = TrajectoryFit({"L": 1.0889, "zeta": 1.1e-24}, {"L": 0.01, "zeta": 0.01}, 0.04, np.zeros((5, 1)), True)
    params = {"L": ParamSpec(init=1.0, min=0.0), "zeta": ParamSpec(init=0.1, min=0.0)}
    moved = off_bounds(lead, {"L": 2.5, "zeta": 0.02}, params)
    # zeta sat on its bound 0, where exp(u) has no slope: it starts again from the restart's 0.02
    assert moved.values == {"L": 1.0889, "zeta": 0.02} and lead.values["zeta"] == 1.1e-24
    assert off_bounds(TrajectoryFit({"L": 1.0889, "zeta": 1e-4}, {}, 0.04, np.zeros((5, 1)), True),
                      {"L": 2.5, "zeta": 0.02}, params).values["zeta"] == 1e-4  # small, yet off its bound
    upper = {"e": ParamSpec(init=0.5, min=0.0, max=1.0)}
    assert off_bounds(TrajectoryFit({"e": 1.0 - 1e-12}, {}, 0.1, np.zeros((5, 1)), True), {"e": 0.7},
                      upper).values == {"e": 0.7}


def test_a_whole_path_fit_stopped_at_its_bound_is_fitted_once_more(monkeypatch):
    # the second fit is kept only where it settles and misfits no more than the first
    from fitode.train import direct
    from fitode.train.trajectory import TrajectoryFit

    def fit(misfit, converged, value):
        return TrajectoryFit({"k": value}, {"k": 0.1}, misfit, np.zeros((5, 1)), converged)
    first = fit(1.0, False, 2.0)
    for second, kept in ((fit(0.9, True, 2.5), 2.5), (fit(1.1, True, 2.5), 2.0), (fit(0.9, False, 2.5), 2.0),
                         (None, 2.0)):
        seen = []
        monkeypatch.setattr(direct, "full_fit", lambda *a, lead=None, **k: seen.append(a[4]) or second)
        got = direct._continued(None, {}, np.zeros((5, 1)), 0.1, first, {"gauge": None})
        assert seen == [first] and got.values["k"] == kept
