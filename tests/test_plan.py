"""fitode.train.plan and the API's three steps: every choice resolved once, recorded the same everywhere."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import fitode
from fitode import api, cli
from fitode.errors import ConfigError, FitodeError
from fitode.examples.make_example import pendulum_angles, render_pendulum, write_mp4
from fitode.train.plan import CHOICES, FitPlan


def _frames(n=60):
    t = np.arange(n) * 0.1
    yy, xx = np.mgrid[:16, :16]
    return np.array([np.exp(-((xx - 8 - 4 * np.cos(2 * s)) ** 2 + (yy - 8) ** 2) / 6) for s in t], np.float32)


def test_the_plan_resolves_every_auto_choice_once_with_its_reason():
    req = api.request(eq="x'' = -w*x - c*x'", restarts=2)
    assert req.config.window is None and req.config.encoder == "auto"
    plan = api.plan(req, api.as_frames(_frames()), 0.1)
    assert set(plan.choices) == set(CHOICES)
    assert plan.config.window == plan.choices["window"].value and plan.config.window >= 3
    assert plan.config.encoder == plan.choices["encoder"].value == "mlp"
    assert plan.observation.name == plan.choices["observation"].value and "auto" in plan.choices["observation"].reason
    lines = plan.lines()
    assert lines[0].startswith("training: 2 restarts") and any(line.startswith("window: auto") for line in lines)
    asked = api.plan(api.request(eq="x'' = -w*x - c*x'", window=12, encoder="cnn"), api.as_frames(_frames()), 0.1)
    assert asked.choices["window"].reason.endswith("as asked)") and asked.choices["encoder"].value == "cnn"


def test_a_plan_refuses_unresolved_choices():
    plan = api.plan(api.request(eq="x'' = -w*x"), api.as_frames(_frames()), 0.1)
    from dataclasses import replace
    with pytest.raises(ValueError, match="concrete window"):
        replace(plan, config=replace(plan.config, window=None))
    with pytest.raises(ValueError, match="concrete window"):
        replace(plan, config=replace(plan.config, encoder="auto"))
    assert isinstance(plan, FitPlan)


def test_the_request_checks_everything_that_needs_no_frames():
    with pytest.raises(ConfigError, match="observation model 'shape'"):
        api.request(eq="x'' = -w*x", observe="shape")
    with pytest.raises(FitodeError, match="not a state"):
        api.request(eq="x'' = -w*x", calibrate="y(0)=1; y(1)=2")
    with pytest.raises(ConfigError, match="unknown training option"):
        api.request(eq="x'' = -w*x", windw=20)
    with pytest.raises(FitodeError, match="fewer than one window"):
        api.plan(api.request(eq="x'' = -w*x", window=80), api.as_frames(_frames()), 0.1)


@pytest.mark.slow
def test_the_header_result_json_and_fit_json_record_the_same_choices(tmp_path, capsys):
    angles = pendulum_angles(120, 30.0, 0.25, 0.15, math.radians(12.0))
    video = write_mp4(tmp_path / "p.mp4", render_pendulum(angles, size=24), 30.0)
    out = tmp_path / "run"
    assert cli.main([str(video), "--eq", "x'' = -w*x - c*x'", "--restarts", "1", "--max-steps", "40",
                     "--min-steps", "40", "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    result = json.loads((out / "result.json").read_text())
    fit = json.loads((out / "fit.json").read_text())
    assert result["plan"] == fit["meta"]["plan"]
    for name in CHOICES:
        reason = result["plan"][name]["reason"]
        assert f"{name}: {reason}" in printed, (name, reason)
    assert result["settings"]["window"] == fit["settings"]["window"] == result["plan"]["window"]["value"]
    assert result["settings"]["encoder"] == fit["settings"]["encoder"] == result["plan"]["encoder"]["value"]
    # 40 steps cannot settle: not trusted, whatever else holds
    assert all(p["verdict"] != "trusted" for p in result["parameters"].values())


def _falling_disc(n=48, dt=1 / 60, g=250.0):
    h, w, r = 110, 24, 3.0
    d = 10 + 0.5 * g * (np.arange(n) * dt) ** 2
    yy, xx = np.mgrid[:h, :w]
    rng = np.random.default_rng(0)
    wall = 0.4 + 0.05 * rng.random((h, w))
    frames = [wall * (1 - c) + 0.9 * c + 0.01 * rng.standard_normal((h, w))
              for c in (np.clip(r + 0.5 - np.hypot(xx + 0.5 - 12, yy + 0.5 - y), 0, 1) for y in d)]
    return np.clip(np.array(frames, np.float32), 0, 1), d, dt


@pytest.mark.slow
def test_fit_calibrates_behind_the_api_and_judges_the_calibrated_value(tmp_path):
    # the disc's place is measured in source pixels along its line of motion, so uncalibrated g is
    # in px/s^2 (trusted); --calibrate in metres (2 mm a pixel) maps it through the scale into the
    # unit the equation file gives
    frames, d, dt = _falling_disc()
    t_end = (len(d) - 1) * dt
    metres_per_px = 0.002
    eq_file = tmp_path / "fall.toml"
    eq_file.write_text('name = "fall"\nequation = "d\'\' = g"\nobserve = "position"\n\n'
                       '[parameters]\ng = { init = 1.0, unit = "m/s^2" }\n')
    res = fitode.fit(frames, dt, eq_file=str(eq_file), progress=False,
                     calibrate=f"d(0)={metres_per_px * d[0]:.6f}; d({t_end:.6f})={metres_per_px * d[-1]:.6f}")
    g = res.parameters["g"]
    assert g.calibrated and g.unit == "m/s^2" and g.latent_value is not None, g
    assert abs(g.latent_value / 250.0 - 1) < 0.03, g  # the measured path's px/s^2
    assert abs(g.value / (250.0 * metres_per_px) - 1) < 0.03, g
    scale = res.calibration["maps"]["d"]["a"]
    assert abs(scale / metres_per_px - 1) < 0.03 and g.value == pytest.approx(scale * g.latent_value, rel=1e-9)
    assert res.verdicts["g"]["verdict"] == "trusted", res.verdicts
    assert res.calibration["maps"]["d"]["n_points"] == 2
    raw = fitode.fit(frames, dt, eq="d'' = g", free=["g"], progress=False)
    assert not raw.parameters["g"].calibrated and raw.parameters["g"].unit == "px/s^2", raw.parameters["g"]
    assert raw.values["g"] == pytest.approx(g.latent_value, rel=1e-6)
    assert raw.verdicts["g"]["verdict"] == "trusted", raw.verdicts


def test_the_header_says_a_measured_path_is_fitted_directly_not_trained():
    # a measured place is fitted by the equation's trajectory; the training line would promise
    # restarts and steps that never run
    plan = api.plan(api.request(eq="x'' = -w*x - c*x'", restarts=3, observe="position"),
                    api.as_frames(_frames()), 0.1)
    assert plan.observation.applies("direct")
    first = plan.lines()[0]
    assert first.startswith("fit: the measured path directly, 3 starting points") and "if that fails" in first
    free = api.plan(api.request(eq="x'' = -w*x - c*x'", restarts=3, observe="any"), api.as_frames(_frames()), 0.1)
    assert free.lines()[0].startswith("training: 3 restarts")
