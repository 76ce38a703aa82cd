"""Model comparison: blocked cross-validation along time (fitode.train.crossval) on arrays, and
candidate equations compared on small generated clips (fitode.compare through fitode.fit)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import fitode
from fitode.eqparse import parse
from fitode.errors import ConfigError, FitodeError
from fitode.synth.trajectory import simulate_system
from fitode.train.crossval import HeldOut, blocks_of, held_out, rank
from fitode.train.trajectory import fit_trajectory, long_options

PENDULUM = "theta'' = -g/L*sin(theta) - zeta*theta'"
LINEAR = "theta'' = -g/L*theta - zeta*theta'"


def _path(text: str, constants: dict, y0: dict, n: int, dt: float, noise: float, seed: int = 0) -> np.ndarray:
    latent, *_ = simulate_system(parse(text), constants, y0, n, dt, substeps=20)
    return latent + noise * np.random.default_rng(seed).standard_normal(latent.shape)


def _ball(rows: np.ndarray, cols: np.ndarray, h: int, w: int, r: float = 2.5, seed: int = 0) -> np.ndarray:
    """Frames (T, H, W) in [0, 1] of a bright ball at the given centres on a dim textured wall."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:h, :w]
    wall = 0.3 + 0.05 * np.sin(xx / 5.0) * np.cos(yy / 7.0)
    frames = [np.clip(wall * (1 - c) + 0.9 * c + rng.normal(0, 0.01, (h, w)), 0, 1)
              for c in (np.clip(r + 0.5 - np.hypot(xx - x, yy - y), 0, 1) for y, x in zip(rows, cols))]
    return np.array(frames, dtype=np.float32)


# --- the cross-validation core, on arrays ----------------------------------------------------

def test_blocks_cover_the_path_contiguously():
    cut = blocks_of(103, 5)
    assert cut[0][0] == 0 and cut[-1][1] == 103
    assert all(a[1] == b[0] for a, b in zip(cut, cut[1:]))
    assert max(b - a for a, b in cut) - min(b - a for a, b in cut) <= 1
    with pytest.raises(ValueError):
        blocks_of(10, 5)


def test_a_held_out_block_is_predicted_by_a_trajectory_through_it():
    system = parse(PENDULUM)
    x = _path(PENDULUM, {"L": 0.5, "zeta": 0.3}, {"theta": 0.8}, 150, 1 / 30, 0.002)
    held = held_out(system, {}, x, 1 / 30, {"L": 0.5, "zeta": 0.3})
    assert len(held.errors) == 5 and np.all(np.isfinite(held.errors))
    # each block is predicted at about the noise (0.002 rad) in spreads of the path
    assert held.error < 3 * 0.002 / x.std()
    assert all(v["L"] == pytest.approx(0.5, rel=0.01) for v in held.values)
    # the fit without a block does not see it: a block replaced by nonsense leaves its prediction alone
    spoiled = x.copy()
    spoiled[60:90] += 0.5
    keep = np.ones(len(x), bool)
    keep[60:90] = False
    clean = fit_trajectory(system, {}, spoiled, 1 / 30, {"L": 0.5, "zeta": 0.3}, keep=keep, **long_options(len(x)))
    assert clean.values["L"] == pytest.approx(0.5, rel=0.01)
    assert np.sqrt(np.mean((clean.residuals[60:90] + 0.5) ** 2)) < 0.01


def test_a_large_swing_tells_the_sine_from_the_linear_pendulum_and_a_small_one_cannot():
    for deg, tells in ((50, True), (5, False)):
        x = _path(PENDULUM, {"L": 0.5, "zeta": 0.3}, {"theta": math.radians(deg)}, 150, 1 / 30, 0.003)
        held = []
        for text in (PENDULUM, LINEAR):
            system = parse(text)
            start = fit_trajectory(system, {}, x, 1 / 30, {"L": 0.5, "zeta": 0.3}, **long_options(len(x)))
            held.append(held_out(system, {}, x, 1 / 30, start.values))
        ranking = rank(held, names=["sine", "linear"])
        assert (ranking.preferred == 0) is tells, ranking.reason
        if not tells:
            assert ranking.preferred is None and "cannot tell" in ranking.reason
            assert ranking.verdicts == ["cannot tell apart", "cannot tell apart"]
        else:
            assert ranking.verdicts == ["preferred", "worse"]


def test_the_ranking_rule_needs_a_consistent_and_large_enough_difference():
    cut = blocks_of(50, 5)
    base = HeldOut(cut, np.array([1.0, 1.1, 0.9, 1.0, 1.05]))
    clear = HeldOut(cut, base.errors * np.array([2.0, 2.2, 1.9, 2.1, 2.0]))
    assert rank([clear, base]).preferred == 1
    # one block far worse, the others equal: the mean ratio is large, its uncertainty larger
    erratic = HeldOut(cut, base.errors * np.array([1.0, 1.0, 9.0, 1.0, 0.9]))
    assert rank([base, erratic]).preferred is None
    # consistent but small: 3% everywhere is below what another fit of the same frames gives
    small = HeldOut(cut, base.errors * 1.03)
    assert rank([base, small]).preferred is None
    failed = HeldOut(cut, np.array([1.0, math.inf, 1.0, 1.0, 1.0]))
    ranking = rank([failed, base])
    assert ranking.preferred == 1 and ranking.verdicts[0] == "failed"


# --- candidates on generated clips -----------------------------------------------------------

def test_candidates_with_different_state_counts_are_refused_in_one_line():
    from fitode import api
    with pytest.raises(ConfigError, match="same measured states"):
        api.requests(eq=["x'' = -k*x", "x' = v; v' = -k*x - c*v"])
    with pytest.raises(ConfigError, match="no candidate"):
        api.requests(eq=["x'' = -k*x", "x'' = -k*x - c*x'"], const={"q": 1.0})
    reqs = api.requests(eq=["x'' = -k*x", "x'' = -k*x - c*x'"], const={"c": 0.1})
    assert [r.equation for r in reqs] == ["x'' = -k*x", "x'' = -k*x - c*x'"]
    assert reqs[1].system.fixed["c"] == 0.1 and reqs[0].system.learnable == ("k",)


def test_a_free_latent_is_not_compared():
    rng = np.random.default_rng(0)
    frames = rng.random((60, 8, 8)).astype(np.float32)
    with pytest.raises(FitodeError, match="measured path"):
        fitode.fit(frames, 0.05, eq=["x'' = -k*x", "x'' = -k*x - c*x'"], observe="any", restarts=1, progress=False)


def _swing(deg: float) -> tuple[np.ndarray, float, str | None]:
    """A ball on a pendulum (L 0.5 m, zeta 0.3 /s) released from `deg` degrees: 5 s at 30 fps. A
    large swing bends visibly about its pivot (read as an angle); a 5-degree one does not (its
    pivot 300 px above the frame: read as a position)."""
    dt = 1 / 30
    th = _path(PENDULUM, {"L": 0.5, "zeta": 0.3}, {"theta": math.radians(deg)}, 150, dt, 0.0)[:, 0]
    if deg < 10:
        return _ball(30 + 300 * (np.cos(th) - 1), 64 + 300 * np.sin(th), 60, 128), dt, "position"
    return _ball(-10 + 50 * np.cos(th), 64 + 50 * np.sin(th), 72, 128), dt, None


def _compared(frames, dt, eqs, **kw) -> dict:
    result = fitode.fit(frames, dt, eq=eqs, restarts=1, progress=False, **kw)
    comparison = result.meta["comparison"]
    assert [c["equation"] for c in comparison["candidates"]] == eqs
    assert comparison["reported"] == (comparison["preferred"] or eqs[0])
    assert result.equation == comparison["reported"]
    return comparison


def test_every_candidate_is_scored_on_the_widest_stretch_any_of_them_explains(monkeypatch):
    # a wrong equation's own stretch is the part of the clip it happens to fit (a linear pendulum
    # on a 50-degree swing kept frames 82-149 of 150); scored there, nothing told the two apart
    from types import SimpleNamespace

    from fitode import api, compare as cmp

    class Scored(Exception):
        pass

    class Result(SimpleNamespace):
        @property
        def latent(self):
            raise Scored  # the stretches are settled once the scoring reads the path

    own = {LINEAR: (82, 150), PENDULUM: (0, 150)}
    calls = []

    def execute(req, plan, frames, stretch=None, **_):
        calls.append((req.equation, stretch))
        a, b = stretch or own[req.equation]
        return Result(meta={"direct": True, "stretch": {"start_frame": a, "end_frame": b, "start_s": a / 30,
                                                         "end_s": b / 30, "reason": "r", "source": "found"}},
                      checks={})

    observation = SimpleNamespace(measured=True, may_measure=True, name="angle")
    monkeypatch.setattr(api, "plan", lambda req, *a, **k: SimpleNamespace(observation=observation))
    monkeypatch.setattr(api, "execute", execute)
    requests = [SimpleNamespace(equation=eq, system=parse(eq), observe=None, observe_source=None)
                for eq in (LINEAR, PENDULUM)]
    monkeypatch.setattr(cmp, "replace", lambda req, **kw: SimpleNamespace(**{**vars(req), **kw}))
    with pytest.raises(Scored):
        cmp.compare(requests, np.zeros((150, 1, 4, 4), np.float32), 1 / 30)
    assert calls == [(LINEAR, None), (PENDULUM, None), (LINEAR, (0, 150))]


@pytest.mark.slow
@pytest.mark.long
def test_a_50_degree_swing_prefers_the_sine():
    comparison = _compared(*_swing(50)[:2], [LINEAR, PENDULUM])
    assert comparison["preferred"] == PENDULUM, comparison["reason"]
    sine = comparison["candidates"][1]
    assert sine["verdict"] == "preferred" and sine["parameters"]["L"]["value"] == pytest.approx(0.5, rel=0.01)
    lo, hi = sine["parameters"]["L"]["interval"]
    assert lo < sine["parameters"]["L"]["value"] < hi


@pytest.mark.slow
@pytest.mark.long
def test_a_5_degree_swing_cannot_tell():
    frames, dt, observe = _swing(5)
    comparison = _compared(frames, dt, [PENDULUM, LINEAR], observe=observe)
    assert comparison["preferred"] is None and "cannot tell" in comparison["reason"]
    assert {c["verdict"] for c in comparison["candidates"]} == {"cannot tell apart"}


@pytest.mark.slow
@pytest.mark.long
def test_a_fall_with_strong_drag_prefers_the_drag():
    # y up (a state named y reads the image's vertical, upwards): the drag pulls up, -k*y'*|y'| > 0
    dt = 1 / 60
    y = _path("y'' = -g - k*y'*abs(y')", {"k": 0.5}, {"y": 0.0, "y'": 0.0}, 90, dt, 0.0)[:, 0]
    drag, plain = "y'' = -g - k*y'*abs(y')", "y'' = -g"
    comparison = _compared(_ball(8 - 25 * y, 30 + 0 * y, 140, 60), dt, [plain, drag], free=["g"])
    assert comparison["preferred"] == drag, comparison["reason"]
    errors = [c["heldout_error"] for c in comparison["candidates"]]
    assert errors[0] > 3 * errors[1]


@pytest.mark.slow
@pytest.mark.long
def test_a_draining_tank_prefers_torricelli():
    dt = 1 / 15
    h = _path("h' = -k*sqrt(h)", {"k": 0.05}, {"h": 0.23}, 200, dt, 0.0)[:, 0]
    comparison = _compared(_ball(100 - 400 * h, 40 + 0 * h, 110, 80), dt, ["h' = -k*h", "h' = -k*sqrt(h)"])
    assert comparison["preferred"] == "h' = -k*sqrt(h)", comparison["reason"]


def test_an_equation_file_lists_alternatives(tmp_path):
    from fitode import api
    from fitode.eqfile import load_equation_file
    path = tmp_path / "swing.toml"
    path.write_text('name = "swing"\nequation = "%s"\nalternatives = ["theta\'\' = -g/L*theta"]\n'
                    "[parameters]\nL = { init = 1.0, min = 0.0 }\nzeta = { init = 0.1 }\n" % PENDULUM)
    spec = load_equation_file(path)
    assert spec.candidates == [PENDULUM, "theta'' = -g/L*theta"]
    assert set(spec.candidate(1).parameters) == {"L"}  # zeta is the first candidate's alone
    reqs = api.requests(eq_file=str(path))
    assert [r.equation for r in reqs] == spec.candidates and reqs[1].system.learnable == ("L",)
    assert len(api.requests(system="pendulum")) == 1  # a file without alternatives: one equation, as before
    path.write_text('name = "bad"\nequation = "%s"\nalternatives = "x"\n' % PENDULUM)
    with pytest.raises(FitodeError, match="alternatives"):
        load_equation_file(path)


@pytest.mark.slow
def test_a_lamp_that_dims_as_one_pattern_is_compared_on_its_light():
    # a lamp's light read linearly is a measured path (fitted directly), so its candidates are
    # compared on one path; before, the brightness observation was refused as a free latent
    from fitode.examples.make_example import decay_values, render_glow
    frames = render_glow(decay_values(80, 20.0, 0.8), size=24).astype(np.float32)
    comparison = _compared(frames, 0.05, ["I' = -gamma*I", "I' = -gamma*I^2"], light="linear")
    assert all(c["verdict"] != "failed" for c in comparison["candidates"]), comparison
