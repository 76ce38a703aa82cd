"""Reports and plots without training: result.json content, the table's warnings, valid PNGs."""
import json
import math
from dataclasses import asdict

import cv2
import numpy as np
import pytest

from fitode import plots
from fitode.report import complete_report, format_table, write_json, _num
from fitode.train.result import Estimate, FitResult, RunRecord

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def assert_png(path):
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape[0] > 100 and img.shape[1] > 100
    assert img.std() > 5  # not a blank canvas


def history(n, start, end, seed=0):
    rng = np.random.default_rng(seed)
    steps = list(range(1, n + 1))
    vals = list(end + (start - end) * np.exp(-np.arange(n) / (n / 6)) + rng.normal(0, 1e-3, n))
    loss = list(np.exp(-np.arange(n) / (n / 4)) + 1e-3)
    return {"step": steps, "loss": loss, "mse": loss, "kl": [0.0] * n, "constants": {"k": vals, "w": vals}}


def result(values, finals, statuses=None, converged=True):
    """A FitResult with one run per entry of finals ({name: value})."""
    statuses = statuses or ["ok"] * len(finals)
    runs = []
    for i, (f, st) in enumerate(zip(finals, statuses)):
        h = history(50, start=float(i + 1), end=f["k"], seed=i)
        runs.append(RunRecord(index=i, seed=i, init={"k": float(i + 1), "w": float(i + 1)}, final=f,
                              loss=0.01 * (i + 1) if st == "ok" else math.nan, steps=50, status=st,
                              error=None if st == "ok" else "loss became non-finite at step 50",
                              converged=converged, history=h))
    ok = [r.index for r in runs if r.status == "ok"]
    t = np.arange(40) * 0.1
    z = np.cos(2 * t)[:, None]
    params = {}
    for name in values:
        v = np.array([finals[i][name] for i in ok])
        params[name] = Estimate(float(v.mean()), float(v.std()), len(v), "m" if name == "w" else None)
    return FitResult(parameters=params, runs=runs, selected=ok, best=ok[0], latent=z, rollout=z * 1.01, time=t,
                     train_frames=32, dt=0.1, states=["x"], equation="x'' = -w*x - k*x'", fixed={},
                     settings={"window": 10, "integrator": "rk4"})


def base():
    return {"status": "running", "equation": {"units": {"w": "m"}}, "warnings": [], "parameters": {},
            "calibration": None}


def analysis(**scales):
    return {"constants": {k: {"separable": v != "combination", "combination": "k*w" if v == "combination" else None,
                              "scale": None if v == "combination" else v, "reason": "test"}
                          for k, v in scales.items()}, "lines": []}


def test_complete_report_fills_estimates_runs_and_trajectory():
    res = result(["k", "w"], [{"k": 1.0, "w": 4.0}, {"k": 1.01, "w": 4.01}])
    rep = base()
    complete_report(rep, res, analysis(k="free", w="free"), t0=2.0)
    assert rep["status"] == "complete"
    assert rep["parameters"]["w"]["value"] == pytest.approx(4.005)
    assert rep["parameters"]["w"]["std"] == pytest.approx(0.005)
    assert rep["parameters"]["w"]["unit"] == "m" and rep["parameters"]["k"]["unit"] is None
    assert [r["selected"] for r in rep["runs"]] == [True, True]
    assert all("history" not in r for r in rep["runs"])  # histories live in fit.json
    assert rep["trajectory"]["time"][0] == 2.0 and len(rep["trajectory"]["latent"]) == 40
    assert rep["warnings"] == [] and rep["notes"] == []
    json.dumps(rep, allow_nan=False)


def test_the_report_prints_the_assessment_and_judges_nothing_itself():
    res = result(["k", "w"], [{"k": 1.0, "w": 4.0}, {"k": 1.5, "w": 4.01}, {"k": 9.0, "w": 9.0}],
                 statuses=["ok", "ok", "failed"], converged=False)
    res.warnings, res.notes = ["k: something the assessment found"], ["1 of 3 restarts failed (runs 3)"]
    rep = base()
    complete_report(rep, res, analysis(k="dependent", w="combination"))
    text = format_table(rep)
    assert rep["parameters"]["k"]["latent_units"] and not rep["parameters"]["w"]["measurable"]
    assert "warning: k: something the assessment found" in text and "note: 1 of 3 restarts failed" in text
    assert "latent units" in text.splitlines()[2]  # the unit column says so
    rows = [line for line in text.splitlines() if line.startswith("  k ") or line.startswith("  w ")]
    # no verdict was made for this hand-built result: the table must not present it as trusted
    assert len(rows) == 2 and all(r.rstrip().endswith("NOT TRUSTWORTHY") for r in rows)


def test_calibrated_constant_is_not_in_latent_units():
    res = result(["k", "w"], [{"k": 0.025, "w": 4.0}])
    res.parameters["k"] = Estimate(0.05, 0.001, 1, calibrated=True, latent_value=0.025)
    res.calibration = {"maps": {"x": {"a": 2.0, "b": 0.1, "n_points": 2, "rms": 0.0}},
                       "latent": np.zeros((40, 1)).tolist(), "rollout": np.zeros((40, 1)).tolist()}
    rep = base()
    complete_report(rep, res, analysis(k="dependent", w="free"))
    assert rep["parameters"]["k"]["value"] == 0.05 and rep["parameters"]["k"]["calibrated"]
    assert rep["parameters"]["k"]["latent_value"] == 0.025
    assert not rep["parameters"]["k"]["latent_units"]
    assert rep["trajectory"]["units"] == "physical" and "latent" not in rep["calibration"]
    assert "x = 2*latent + 0.1" in format_table(rep)


def test_write_json_has_no_nan(tmp_path):
    p = write_json({"a": math.nan, "b": [1.0, math.inf], "c": np.arange(3.0)}, tmp_path / "r.json")
    assert json.loads(p.read_text()) == {"a": None, "b": [1.0, None], "c": [0.0, 1.0, 2.0]}


@pytest.mark.parametrize("v, text", [(4.0016, "4.0016"), (0.08, "0.080000"), (123.456, "123.46"),
                                     (1.5e-5, "1.5000e-05"), (0.0, "0"), (math.nan, "nan")])
def test_number_format_keeps_five_significant_digits(v, text):
    assert _num(v) == text


def test_plots_are_valid_pngs(tmp_path):
    res = result(["k", "w"], [{"k": 1.0, "w": 4.0}, {"k": 1.1, "w": 4.1}, {"k": 3.0, "w": 3.0}],
                 statuses=["ok", "ok", "failed"])
    runs = [dict(asdict(r), selected=r.index in res.selected) for r in res.runs]  # as the pipeline passes them
    rollout = res.rollout.copy()
    rollout[30:] = np.nan  # a rollout that left the finite range must not break the plot
    plots.plot_latent(tmp_path / "latent.png", res.time, res.latent, rollout, 32, ["x"], window=10)
    plots.plot_params(tmp_path / "params.png", runs, {"k": 1.05, "w": 4.05}, units={"w": "m"})
    plots.plot_loss(tmp_path / "loss.png", runs)
    frames = np.random.default_rng(0).random((30, 1, 24, 32)).astype(np.float32)
    plots.plot_frames(tmp_path / "frames.png", frames, 0.1, t0=1.0)
    two = np.random.default_rng(0).normal(size=(40, 2))
    plots.plot_latent(tmp_path / "latent2.png", res.time, two, two, 40, ["u", "v"], ylabels=["u [m]", "v [m]"])
    for name in ("latent", "params", "loss", "frames", "latent2"):
        assert_png(tmp_path / f"{name}.png")


def test_a_measured_path_is_drawn_as_measured_with_its_fitted_trajectory_and_no_window():
    t = np.arange(40) * 0.1
    path = np.sin(t)[:, None]
    encoded = plots.latent_figure(t, path, path, 40, ["x"], window=10)
    measured = plots.latent_figure(t, path, path, 40, ["x"], window=10, measured=True)
    labels = lambda fig: [h.get_label() for h in fig.axes[0].get_lines()]  # noqa: E731
    assert "encoded frames" in labels(encoded) and any("window" in s for s in labels(encoded))
    assert labels(measured)[:2] == ["measured frames", "the equation's trajectory fitted to them"]
    assert not any("window" in s for s in labels(measured))
    assert measured._suptitle.get_text() == "the measured path and the equation's trajectory"
