"""Observation models as plug-ins: a model defined here, in the test, fits through fitode.fit
with nothing changed elsewhere, in the state's own units or in the latent's; several states
fit as measured columns; the catalog is the one list of names the command line, equation files
and `fitode check` read; what a model means is asked of the model."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import torch

import fitode
from fitode.eqparse import parse
from fitode.errors import ConfigError, FitodeError
from fitode.train.observe import (CHOICES, MODELS, BrightnessObservation, DistanceObservation, MeasuredObservation,
                                  ObservationModel, PositionObservation, Prepared, SizeObservation, model_class,
                                  parse_observe, resolve_observation)


class PixelTracker(MeasuredObservation):
    """A tracker that reads each state from one pixel of the frame: pixel (0, j) holds state j's
    value. units: "physical" (the value is the state in its own units) or "latent" (the reading is
    standardised, as a centroid in pixels would be)."""

    name = "pixel-tracker"

    def __init__(self, states: tuple[str, ...], physical: bool):
        super().__init__()
        self.physical_units = physical
        self.measures = states

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        k = len(self.measures)
        z = frames[:, 0, 0, :k].double()
        if not self.physical_units:
            z = (z - z.mean(dim=0)) / z.std(dim=0)
        return Prepared(z.to(frames.dtype).reshape(-1, k, 1, 1), z.numpy().copy(), k, "read from the top pixels",
                        states=self.measures)


def _frames(columns: np.ndarray) -> np.ndarray:
    """(T, 1, 2, k) frames whose top row holds the path's columns (T, k), the rest grey."""
    columns = np.asarray(columns, dtype=np.float64).reshape(len(columns), -1)
    out = np.full((len(columns), 1, 2, columns.shape[1]), 0.5)
    out[:, 0, 0, :] = columns
    return out


FAST = dict(restarts=3, window=16, max_steps=1500, progress=False)


@pytest.mark.slow
def test_a_model_that_measures_the_state_in_its_own_units_fixes_a_scale_dependent_constant():
    dt, g = 1 / 30, 7.3  # a fall of 7.3 m/s^2 (a ball rolling down a steep incline), read in metres
    t = np.arange(60) * dt
    y = 1.2 + 0.8 * t - 0.5 * g * t ** 2 + 1e-4 * np.random.default_rng(0).standard_normal(len(t))
    model = PixelTracker(("y",), physical=True)
    res = fitode.fit(_frames(y), dt, eq="y'' = -g", free=["g"], observe=model, **FAST)
    assert abs(res.values["g"] / g - 1) < 0.01, res.values
    verdict = res.verdicts["g"]
    reasons = " ".join([verdict["reason"], *verdict["other_reasons"]])
    assert "units" not in reasons and "calibrat" not in reasons, verdict
    assert verdict["verdict"] == "trusted", verdict
    assert res.meta["own_units"] == [] and res.meta["physical_units"]
    # the gauge is the identity: the state is the latent, read as given
    assert all(abs(run.gauge["y"]["scale"] - 1) < 1e-12 and run.gauge["y"]["offset"] == 0 for run in res.runs)
    np.testing.assert_allclose(res.latent[:, 0], y, atol=1e-5)


@pytest.mark.slow
def test_a_model_in_the_latents_units_leaves_a_scale_dependent_constant_to_calibration():
    dt, g = 1 / 30, 7.3
    t = np.arange(60) * dt
    y = 1.2 + 0.8 * t - 0.5 * g * t ** 2
    res = fitode.fit(_frames(y), dt, eq="y'' = -g", free=["g"], observe=PixelTracker(("y",), physical=False), **FAST)
    verdict = res.verdicts["g"]
    assert verdict["verdict"] == "not trustworthy" and "units" in verdict["reason"], verdict
    # every restart reads the one path in units of its own: g is the best run's, not a mean
    assert not res.meta["physical_units"] and res.meta["own_units"] == ["g"]
    assert res.parameters["g"].n_runs == 1


@pytest.mark.slow
def test_two_states_fit_from_two_measured_columns_given_in_any_order():
    a, b, dt = 4.0, 9.0, 0.05
    t = np.arange(160) * dt
    x = 1.5 * np.cos(2.0 * t + 0.3)
    y = 0.4 * np.sin(3.0 * t + 1.0)
    frames = _frames(np.stack([y, x], axis=1))  # the tracker measures y first
    res = fitode.fit(frames, dt, eq="x'' = -a*x; y'' = -b*y", observe=PixelTracker(("y", "x"), physical=False),
                     **FAST)
    assert abs(res.values["a"] / a - 1) < 0.02 and abs(res.values["b"] / b - 1) < 0.02, res.values
    # each latent dimension reads its own state: x's latent is affine in x, y's in y
    for j, truth in enumerate((x, y)):
        assert abs(np.corrcoef(res.latent[:, j], truth)[0, 1]) > 0.999
    res = fitode.fit(frames, dt, eq="x'' = -a*x; y'' = -b*y", observe=PixelTracker(("y", "x"), physical=True),
                     **FAST)
    assert abs(res.values["a"] / a - 1) < 0.01 and abs(res.values["b"] / b - 1) < 0.01, res.values
    np.testing.assert_allclose(res.latent, np.stack([x, y], axis=1), atol=1e-5)


def test_a_run_whose_measured_column_points_the_other_way_is_aligned_per_state():
    from fitode.eqparse.identify import sign_odd
    from fitode.train.result import RunRecord
    from fitode.train.trainer import _align
    system = parse("x'' = a; y'' = -b*y'")
    t = np.linspace(0, 1, 30)
    best = np.stack([t ** 2, np.exp(-t)], axis=1)
    latents = np.stack([best, best * [1, -1], best * [-1, 1]])  # run 1 reads y the other way, run 2 x
    runs = [RunRecord(index=i, seed=i, init={}, final={"a": v, "b": 2.0}, loss=0.1, steps=1, status="ok")
            for i, v in enumerate([3.0, 3.0, -3.0])]
    _align(runs, latents, 0, lambda cols: sign_odd(system, [system.states[j] for j in cols]), per_column=True)
    assert [r.value("a") for r in runs] == [3.0, 3.0, 3.0] and [r.value("b") for r in runs] == [2.0] * 3
    assert sign_odd(system, ["y"]) == set() and sign_odd(system, ["x"]) == {"a"}


def test_what_a_model_means_is_asked_of_the_model():
    any_, light = ObservationModel(), BrightnessObservation()
    pos, size, dist = PositionObservation(), SizeObservation(), DistanceObservation()
    assert not any_.measured and all(m.measured for m in (pos, size, dist))
    assert any_.applies("score") and any_.applies("quiet") and any_.applies("rivals")
    assert light.applies("score") and not light.applies("quiet")
    assert pos.applies("perspective") and not size.applies("perspective") and not dist.applies("perspective")
    assert all(m.applies("trajectory") and not m.applies("score") for m in (pos, size, dist))
    assert not any(m.physical_units or m.fixes_scale() for m in (any_, light, pos, size, dist))
    assert PixelTracker(("x",), physical=True).fixes_scale()
    with pytest.raises(ValueError):
        pos.applies("nonsense")
    assert pos.describe().startswith("position: the centroid")
    assert PixelTracker(("x",), True).describe().startswith("pixel-tracker: A tracker")
    from fitode.eqparse.gauge import gauge_plan
    system = parse("y' = -k*sqrt(y)")
    learned = gauge_plan(system)["y"]
    assert learned.scale_learned or learned.offset_learned
    fixed = PixelTracker(("y",), True).gauge_plan(gauge_plan(system))["y"]
    assert not fixed.scale_learned and not fixed.offset_learned and "own units" in fixed.reason


def test_the_catalog_names_every_model_once_and_maps_each_to_its_class():
    assert CHOICES == ("auto",) + tuple(MODELS)
    for name in MODELS:
        assert model_class(name).name == name
    from fitode.train.config import OBSERVE_CHOICES
    assert OBSERVE_CHOICES == CHOICES
    code = "import sys, fitode.train.config, fitode.train.observe.catalog; assert 'torch' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_an_observation_per_state_is_parsed_checked_and_combined():
    assert parse_observe("position") == "position"
    assert parse_observe("x=position; y=size") == {"x": "position", "y": "size"}
    assert parse_observe({"x": "distance"}) == {"x": "distance"}
    for bad in ("nowhere", "x=auto", "x=position;y", {"x": "nowhere"}):
        with pytest.raises(ConfigError):
            parse_observe(bad)
    system = parse("x'' = 0; y'' = -g")
    model = resolve_observation({"x": "position", "y": "size"}, system)
    assert model.name == "x=position;y=size" and model.measured and not model.applies("perspective")
    assert "x: position" in model.describe() and "y: size" in model.describe()
    with pytest.raises(ConfigError, match="free latent"):
        resolve_observation("x=any;y=position", system)
    with pytest.raises(ConfigError, match="no model for y"):
        resolve_observation({"x": "position"}, system)


def test_an_equation_file_and_the_command_line_name_an_observation_per_state(tmp_path, capsys):
    from fitode.cmd_check import observation_lines
    from fitode.eqfile import load_equation_file
    path = tmp_path / "two.toml"
    path.write_text('name = "two"\nequation = "x\'\' = -a*x; y\'\' = -b*y"\nobserve = { x = "position", y = "size" }\n')
    spec = load_equation_file(path)
    assert spec.observe == {"x": "position", "y": "size"}
    lines = " ".join(observation_lines(spec.parse(), spec.observe))
    assert "x: position (from the equation file)" in lines and "y: size" in lines
    path.write_text('name = "two"\nequation = "x\'\' = -a*x; y\'\' = -b*y"\nobserve = { x = "position", z = "size" }\n')
    with pytest.raises(FitodeError, match="z, which is not a state"):
        load_equation_file(path)
    path.write_text('name = "two"\nequation = "x\'\' = -a*x"\nobserve = "sideways"\n')
    with pytest.raises(FitodeError, match="sideways"):
        load_equation_file(path)
    from fitode import cli
    assert cli.main(["clip.npy", "--eq", "x'' = -a*x", "--observe", "x=nowhere"]) == 2
    assert "observe x='nowhere'" in capsys.readouterr().err


def test_the_one_states_model_named_for_it_is_that_model():
    """`y=position@1` for an equation of y alone reads as `position@1` does, the perspective
    re-reading included (the per-state model bends no path: its states are several)."""
    from fitode.train.observe import PositionObservation, resolve_observation

    model = resolve_observation("y=position", parse("y'' = -g"))
    assert isinstance(model, PositionObservation) and model.applies("perspective")
    both = resolve_observation("x=position;y=position", parse("x'' = 0; y'' = -g"))
    assert not isinstance(both, PositionObservation) and not both.applies("perspective")
