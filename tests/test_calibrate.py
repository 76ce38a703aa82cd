"""Calibration: strict parsing, the affine map, and the re-fit of constants in physical units.

No training here: a FitResult is built around a latent that is a known affine image of an exact
trajectory, which is what a perfect encoder would give. The re-fit must then return the physical
constants for scale-dependent ones and leave scale-free ones (nearly) unchanged.
"""
import math

import numpy as np
import pytest

from fitode.calibrate import (CalibrationError, CalibrationPoint, calibrate_result, check_times, fit_affine,
                              local_value, on_trajectory, parse_calibration, point_readings)
from fitode.eqparse import ParamSpec, parse
from fitode.train.result import Estimate, FitResult, RunRecord


def fake_result(system, time, latent, values, std=None):
    """A FitResult as the trainer would return it for a perfect encoder with these constants."""
    latent = np.asarray(latent, dtype=float).reshape(len(time), -1)
    std = std or {}
    return FitResult(
        parameters={k: Estimate(v, std.get(k, 0.0), 3) for k, v in values.items()},
        runs=[RunRecord(index=0, seed=0, init={}, final=dict(values), loss=1e-4, steps=500, status="ok",
                        converged=True)],
        selected=[0], best=0, latent=latent, rollout=latent.copy(), time=np.asarray(time, dtype=float),
        train_frames=len(time), dt=float(time[1] - time[0]), states=list(system.states), equation=system.text,
        fixed=dict(system.fixed), settings={"window": 20, "integrator": "rk4", "substeps": 1})


def analysis(**scales):
    return {"constants": {k: {"separable": True, "combination": None, "scale": v, "reason": ""}
                          for k, v in scales.items()}, "lines": []}


# ----------------------------------------------------------------------------- parsing
def test_parse_reads_items_and_whitespace():
    pts = parse_calibration(" h(0)=0.07; h( 25 ) = 1e-2 \n h(12.5)=0.04", ["h"])
    assert pts == [CalibrationPoint("h", 0.0, 0.07), CalibrationPoint("h", 25.0, 0.01),
                   CalibrationPoint("h", 12.5, 0.04)]


@pytest.mark.parametrize("text, words", [
    ("", "empty"),
    ("x(0)=1; x(2)=3", "not a state"),
    ("h(0)=1", "two or more"),
    ("h(0)=1; h(0)=2", "two or more"),
    ("h(0)=1; h(3)=1", "all equal"),
    ("h(0)=1, h(3)=2", "not a number"),
    ("h(a)=1; h(3)=2", "not a number"),
    ("h'(0)=1; h'(3)=2", "derivative"),
    ("h(0)=inf; h(3)=2", "not finite"),
    ("h 0 = 1", "cannot read"),
])
def test_parse_errors_are_one_line(text, words):
    with pytest.raises(CalibrationError) as e:
        parse_calibration(text, ["h"])
    assert words in str(e.value) and "\n" not in str(e.value)


def test_times_must_lie_inside_the_clip():
    pts = parse_calibration("h(0)=1; h(30)=2", ["h"])
    check_times(pts, 30.0)
    with pytest.raises(CalibrationError, match="outside the clip"):
        check_times(pts, 29.0)
    with pytest.raises(CalibrationError, match="outside the clip"):
        check_times(pts, 1.0, 40.0)
    # a time typed rounded past the last frame (30.004 for 30.0) names that frame within half a frame
    rounded = parse_calibration("h(0)=1; h(30.004)=2", ["h"])
    check_times(rounded, 0.0, 30.0, slack=0.005)
    with pytest.raises(CalibrationError, match="outside the clip"):
        check_times(rounded, 0.0, 30.0, slack=0.003)


def test_affine_map_is_least_squares_on_interpolated_latent():
    t = np.linspace(0, 10, 101)
    z = np.sin(t)[:, None]
    pts = [CalibrationPoint("x", 1.05, 3 * math.sin(1.05) + 2), CalibrationPoint("x", 4.0, 3 * math.sin(4.0) + 2),
           CalibrationPoint("x", 7.33, 3 * math.sin(7.33) + 2 + 0.01)]
    m = fit_affine(pts, t, z, ["x"])["x"]
    assert m.a == pytest.approx(3, rel=3e-3) and m.b == pytest.approx(2, abs=1e-2)
    assert 0 < m.rms < 0.01 and m.n_points == 3


def test_points_are_read_on_the_fitted_trajectory_where_it_covers_them():
    # a reading that errs slowly (a level locked to its pixels) about the trajectory fitted to it:
    # a point is read on that trajectory where it covers the point's frames, else on the reading
    t = np.linspace(0, 10, 101)
    fitted = (2 * t + 1)[:, None]
    raw = fitted + 0.3 * np.cos(3 * t)[:, None]
    fitted[95:] = np.nan  # after the stretch fitted
    pts = [CalibrationPoint("x", 0.0, 0.0), CalibrationPoint("x", 9.8, 1.0)]
    assert on_trajectory(pts, t, fitted, "x", ["x"]) == [True, False]
    z = point_readings(pts, t, raw, "x", ["x"], fitted)
    assert z[0] == pytest.approx(1.0, abs=1e-9)
    assert z[1] == pytest.approx(local_value(t, raw[:, 0], 9.8)) and abs(z[1] - (2 * 9.8 + 1)) > 0.05
    m = fit_affine(pts, t, raw, ["x"], fitted)["x"]
    assert m.a * z[0] + m.b == pytest.approx(0.0, abs=1e-9) and m.a * z[1] + m.b == pytest.approx(1.0)
    # without a fitted trajectory (an encoder's latent), both on the reading
    assert abs(point_readings(pts, t, raw, "x", ["x"])[0] - 1.0) > 0.05


def test_affine_map_refuses_a_flat_latent():
    t = np.linspace(0, 10, 101)
    z = np.ones((101, 1))
    with pytest.raises(CalibrationError, match="hardly changes"):
        fit_affine([CalibrationPoint("x", 1, 0.0), CalibrationPoint("x", 2, 1.0)], t, z, ["x"])


# ----------------------------------------------------------------------------- re-fit
def test_scale_free_constants_come_out_unchanged():
    """z'' + g1 z' + g0 z = 0: both constants survive any affine change of the latent."""
    system = parse("x'' + g1*x' + g0*x = 0")
    t = np.arange(200) * 0.1
    x = 0.05 * np.exp(-0.04 * t) * np.cos(2 * t)  # physical units: a 5 cm swing
    z = (x - 0.01) / 0.03  # an encoder's arbitrary scale and offset
    truth = {"g0": 4.0016, "g1": 0.08}
    res = fake_result(system, t, z, truth)
    pts = parse_calibration(f"x(0)={x[0]}; x(7.3)={np.interp(7.3, t, x)}", ["x"])
    cal = calibrate_result(res, system, {}, pts, analysis(g0="free", g1="free"))
    m = cal.maps["x"]
    assert m.a == pytest.approx(0.03, rel=1e-3) and m.b == pytest.approx(0.01, abs=1e-4)
    np.testing.assert_allclose(cal.latent[:, 0], x, atol=2e-4)
    for name, v in truth.items():
        c = cal.constants[name]
        assert not c["converted"] and c["after"] == v  # scale-free: the estimate is kept
        assert c["refit"] == pytest.approx(v, rel=0.02)  # and the re-fit agrees with it
    assert not cal.notes


def test_scale_dependent_constant_is_converted_to_physical_units():
    """h' = -k*sqrt(h): with z = h/4, the latent-unit k is k/2; calibration must give k back."""
    system = parse("h' = -k*sqrt(h)")
    k, a = 0.05, 4.0
    t = np.arange(150) * 0.15
    h = (1.0 - k * t / 2) ** 2  # exact solution from h(0) = 1
    z = h / a
    res = fake_result(system, t, z, {"k": k / math.sqrt(a)}, std={"k": 0.001})
    pts = parse_calibration(f"h(0)={h[0]}; h({t[-1]})={h[-1]}", ["h"])
    params = {"k": ParamSpec(init=0.1, min=0.0, unit="m^0.5/s")}
    cal = calibrate_result(res, system, params, pts, analysis(k="dependent"))
    c = cal.constants["k"]
    assert c["converted"]
    assert c["after"] == pytest.approx(k, rel=0.01)
    assert c["std_after"] == pytest.approx(0.001 * math.sqrt(a), rel=0.02)  # relative spread is kept
    assert np.nanmax(np.abs(cal.rollout[:, 0] - h)) < 0.01
    assert "calibrated" in cal.lines()[1] and "x2" in cal.lines()[1]


def test_without_analysis_every_constant_is_refitted():
    """Free fall of a latent with a flipped sign: y'' = -g needs the sign search."""
    system = parse("y'' = -a")
    t = np.arange(60) * 0.02
    y = 2.0 + 0.5 * t - 9.81 / 2 * t**2
    z = -(y - 1.0) / 3.0  # a negative scale: the latent falls upwards
    res = fake_result(system, t, z, {"a": -9.81 / 3.0})
    pts = parse_calibration(f"y(0)={y[0]}; y({t[40]})={y[40]}", ["y"])
    cal = calibrate_result(res, system, {}, pts, None)
    assert cal.maps["y"].a == pytest.approx(-3.0, rel=1e-3)
    assert cal.constants["a"]["after"] == pytest.approx(9.81, rel=0.01)


# ----------------------------------------------------------------------------- the sliding block
FPS, ACCEL = 240.0, 885.0  # a block on an incline, filmed at 240 fps, tracked in pixels (px/s^2)
WINDOW = 40  # frames: at 240 fps, 20 frames see 3 px of the acceleration, under a starting velocity's noise


def _slide(n: int = 160, noise: float = 0.1, seed: int = 1):
    """The block's position along its path in pixels, x'' = ACCEL from a slow start, with a
    tracker's noise; and the time of each frame."""
    t = np.arange(n) / FPS
    x = 120.0 + 15.0 * t + ACCEL / 2 * t**2
    return t, x + noise * np.random.default_rng(seed).standard_normal(n)


def _block_case():
    from fitode.train.trajectory import fit_trajectory
    system = parse("x'' = a")
    t, x = _slide()
    z = (x - x.mean()) / x.std()  # the latent an encoder reads: the path at its own scale and offset
    windows = fit_trajectory(system, {}, z[:, None], 1 / FPS, {"a": 1.0}, windows=WINDOW)
    whole = fit_trajectory(system, {}, x[:, None], 1 / FPS, {"a": 100.0})
    res = fake_result(system, t, z, {"a": windows.values["a"]}, std={"a": 0.01})
    res.settings["window"] = WINDOW
    pts = parse_calibration(f"x({t[5]})={x[5]}; x({t[150]})={x[150]}", ["x"])
    return system, res, pts, windows, whole


def test_the_sliding_block_gives_one_constant_from_the_windows_the_whole_clip_and_the_calibration():
    system, res, pts, windows, whole = _block_case()
    cal = calibrate_result(res, system, {}, pts, analysis(a="dependent"))
    c, m = cal.constants["a"], cal.maps["x"]
    from_windows = windows.values["a"] * m.a  # the windows' own value mapped by the calibration's scale
    for value in (whole.values["a"], c["after"], c["refit"]):
        assert value == pytest.approx(from_windows, rel=0.01)
    assert from_windows == pytest.approx(ACCEL, rel=0.03)
    assert not cal.findings({})


def test_the_calibration_does_not_move_a_constant_of_an_equation_linear_in_its_state():
    system, res, pts, _, _ = _block_case()
    cal = calibrate_result(res, system, {}, pts, analysis(a="dependent"))
    c = cal.constants["a"]
    assert c["converted"] and c["mapped"] is not None
    assert c["after"] == pytest.approx(c["before"] * cal.maps["x"].a, rel=1e-12)  # exactly the map, never a refit
    assert c["std_after"] == pytest.approx(0.01 * abs(cal.maps["x"].a), rel=1e-12)


def test_a_latent_constant_the_calibrated_trajectory_does_not_bear_out_is_a_finding_not_a_change():
    system, res, pts, windows, _ = _block_case()
    res.parameters["a"] = res.parameters["a"].__class__(windows.values["a"] * 0.8, 0.01, 3)
    res.runs[0].final["a"] = windows.values["a"] * 0.8  # a latent constant 20% off its own trajectory
    cal = calibrate_result(res, system, {}, pts, analysis(a="dependent"))
    c = cal.constants["a"]
    assert c["after"] == pytest.approx(c["before"] * cal.maps["x"].a, rel=1e-12)
    found = cal.findings({})
    assert len(found) == 1 and found[0].level == "ambiguous" and found[0].names == ("a",)
    assert f"{c['mapped_best']:.6g}" in found[0].reason and f"{c['refit']:.6g}" in found[0].reason


@pytest.mark.parametrize("swing", [0.1, 0.8])
def test_an_angle_in_radians_takes_the_power_of_its_scale_that_its_fit_shows(swing):
    """A large swing read as an angle in radians is calibrated by a map a = 1.00002 (the points'
    readings a hair off): L's share of the points' uncertainty is its measured power of the scale
    (about -swing**2/4: L moves with the amplitude) times the scale's relative std, not
    log(ratio)/log(a), which read the refit's own 0.05% difference as a power of 50 (L +-8%)."""
    from fitode.codegen.block import simulate
    system = parse("theta'' = -g/L*sin(theta) - zeta*theta'")
    truth = {"L": 0.9, "zeta": 0.08}
    dt = 1 / 30
    theta = simulate(system, truth, {"theta": [swing, 0.0]}, 150, dt, substeps=10).numpy()[:, 0]
    t = np.arange(150) * dt
    res = fake_result(system, t, theta / 1.00002, truth)
    std = 0.002 * swing  # each point known to 0.2% of the swing
    pts = parse_calibration(f"theta(0)={theta[0]}+-{std}; theta({t[-1]})={theta[-1]}+-{std}", ["theta"])
    params = {"L": ParamSpec(init=1.0, min=0.0, unit="m"), "zeta": ParamSpec(init=0.1)}
    cal = calibrate_result(res, system, params, pts, analysis(L="free-small-amplitude", zeta="free-small-amplitude"))
    m = cal.maps["theta"]
    rel_a = math.hypot(std / theta[0], std / theta[-1]) * abs(1 / (1 - theta[-1] / theta[0]))  # the order of it
    power = swing ** 2 / 4 / (1 + swing ** 2 / 8)
    c = cal.constants["L"]
    assert c["after"] == pytest.approx(0.9, rel=2e-3)
    assert abs(m.a - 1.00002) < 1e-4
    assert c["relative_std"] < 0.01  # was 0.04 and more
    assert c["relative_std"] == pytest.approx(power * rel_a, rel=0.6, abs=2e-6)


def test_the_refit_of_a_calibrated_trajectory_goes_past_a_start_whose_fit_fails(monkeypatch):
    """h' = -k*sqrt(h) with an offset map (no pure power): the two best-ranked starts' fits fail (a
    bounded k that steps out of the domain, as on a generated drain); the constant is still
    converted, from the next start, instead of staying in latent units."""
    import fitode.train.trajectory as tr
    system = parse("h' = -k*sqrt(h)")
    k, t = 0.05, np.arange(150) * 0.15
    h = (1.0 - k * t / 2) ** 2
    z = (h - 0.6) / 0.2  # an encoder's scale and an offset that matters
    res = fake_result(system, t, z, {"k": 0.3})
    pts = parse_calibration(f"h(0)={h[0]}; h({t[-1]})={h[-1]}", ["h"])
    params = {"k": ParamSpec(init=1.0, min=0.0)}
    real, calls = tr.fit_trajectory, []

    def first_fails(*args, **kw):
        calls.append(1)
        return None if len(calls) <= 2 else real(*args, **kw)
    monkeypatch.setattr(tr, "fit_trajectory", first_fails)
    cal = calibrate_result(res, system, params, pts, analysis(k="dependent"))
    c = cal.constants["k"]
    assert len(calls) >= 3 and c["converted"] and not c["unfitted"]
    assert c["after"] == pytest.approx(k, rel=0.02)


def test_a_slow_reading_error_at_the_points_widens_a_constant_the_map_offset_moves():
    """A drain read as a level with slow errors (0.4 mm over about a second, as the generated
    drains show), calibrated at its ends: no scatter about a local quadratic shows such an error,
    yet it moves both points' readings and so k. The relative std must carry it, and cover the
    error it causes."""
    system = parse("h' = -k*sqrt(h)")
    k, h0 = 0.0132, 0.243
    t = np.arange(101) * 0.05
    h = (math.sqrt(h0) - k * t / 2) ** 2  # a level that falls 13% in 5 s
    slow = 4e-4 * np.sin(2 * math.pi * t / 1.3 + 0.4)
    z = (h + slow - 0.2) / 0.01
    res = fake_result(system, t, z, {"k": 0.13})
    res.meta["direct"] = True  # a measured path, fitted as one trajectory
    pts = parse_calibration(f"h(0)={h[0]}; h({t[-1]})={h[-1]}", ["h"])
    cal = calibrate_result(res, system, {"k": ParamSpec(init=1.0, min=0.0)}, pts, analysis(k="dependent"))
    c = cal.constants["k"]
    assert c["converted"] and c["mapped"] is None  # refitted after the map: the offset moves k
    off = abs(c["after"] / k - 1)
    assert 0.004 < c["relative_std"] < 0.05
    assert off < 2.5 * c["relative_std"]


def test_the_fit_of_a_measured_path_whose_zero_the_map_sets_is_the_estimate_itself():
    """A level read in pixels and fitted directly (one path for every restart), calibrated at its
    ends: the map sets the zero that sqrt(h) reads, so k is the fit of the calibrated path, marked
    gauge_fixed; an encoder's latent (not fitted directly) and an equation that does not read the
    state's value (a fall) keep the mapping and the restarts."""
    system = parse("h' = -k*sqrt(h)")
    k, h0 = 0.0132, 0.243
    t = np.arange(101) * 0.05
    h = (math.sqrt(h0) - k * t / 2) ** 2
    pts = parse_calibration(f"h(0)={h[0]}; h({t[-1]})={h[-1]}", ["h"])
    spec = {"k": ParamSpec(init=1.0, min=0.0)}
    direct = fake_result(system, t, (h - 0.2) / 0.01, {"k": 0.13})
    direct.meta["direct"] = True
    cal = calibrate_result(direct, system, spec, pts, analysis(k="dependent"))
    assert cal.gauge_fixed_names() == ["k"] and cal.constants["k"]["after"] == pytest.approx(k, rel=1e-3)
    encoded = fake_result(system, t, (h - 0.2) / 0.01, {"k": 0.13})
    assert calibrate_result(encoded, system, spec, pts, analysis(k="dependent")).gauge_fixed_names() == []
    fall = parse("y'' = -g")
    y = 1.5 - 9.81 * t ** 2 / 2
    falling = fake_result(fall, t, (y - 0.2) / 0.01, {"g": 981.0})
    falling.meta["direct"] = True
    points = parse_calibration(f"y(0)={y[0]}; y({t[-1]})={y[-1]}", ["y"])
    assert calibrate_result(falling, fall, {}, points, analysis(g="dependent")).gauge_fixed_names() == []


def test_the_calibrated_trajectory_is_the_runs_own_fitted_stretch():
    """A swing released after a hold: the run's trajectory covers its stretch only; calibrated, it
    is the same trajectory mapped, not a rollout from the held first frames."""
    system = parse("h' = -k*sqrt(h)")
    k, a = 0.05, 4.0
    t = np.arange(150) * 0.15
    h = np.where(t < 3.0, 1.0, (1.0 - k * np.maximum(t - 3.0, 0.0) / 2) ** 2)  # held until 3 s
    res = fake_result(system, t, h / a, {"k": k / math.sqrt(a)})
    res.rollout[:20] = np.nan  # the stretch the run fitted starts at the release
    pts = parse_calibration(f"h(0)={h[0]}; h({t[-1]})={h[-1]}", ["h"])
    cal = calibrate_result(res, system, {"k": ParamSpec(init=0.1, min=0.0, unit="m^0.5/s")}, pts,
                           analysis(k="dependent"))
    assert np.all(np.isnan(cal.rollout[:20, 0]))
    np.testing.assert_allclose(cal.rollout[20:, 0], h[20:], atol=1e-9)


def test_a_calibration_that_moves_a_measured_constant_beyond_its_rescaling_widens_it_by_that():
    """An angle measured in radians with a zero 6 mrad off and a reading that bends (the measured
    fit refines the zero, and its L is right), calibrated by two exact angles: the map's scale is
    within 1% of one, yet the calibrated refit moves L; the two readings of L disagree, and the
    calibrated value carries the difference (a generated swing: +0.72% with +-0.08%, a false trust)."""
    from fitode.codegen.block import simulate
    system = parse("theta'' = -g/L*sin(theta) - zeta*theta'")
    truth = {"L": 0.9, "zeta": 0.08}
    dt = 1 / 60
    theta = simulate(system, truth, {"theta": [0.7, 0.0]}, 90, dt, substeps=10).numpy()[:, 0]
    t = np.arange(90) * dt  # 1.5 s, two thirds of a swing: the zero and the bend move L
    reading = theta + 0.006 + 0.008 * theta ** 2
    pts = parse_calibration(f"theta(0)={theta[0]}; theta({t[66]})={theta[66]}", ["theta"])
    params = {"L": ParamSpec(init=1.0, min=0.0, unit="m"), "zeta": ParamSpec(init=0.1)}
    scales = analysis(L="free-small-amplitude", zeta="free-small-amplitude")
    plain = calibrate_result(fake_result(system, t, reading, truth), system, params, pts, scales)
    res = fake_result(system, t, reading, truth)
    res.meta["direct"] = True  # a measured path, fitted directly: the reading is in radians already
    cal = calibrate_result(res, system, params, pts, scales)
    c = cal.constants["L"]
    assert abs(abs(cal.maps["theta"].a) - 1) < 0.02
    moved = abs(c["after"] - c["before"]) / c["after"]
    assert moved > 0.005
    assert moved > 3 * plain.constants["L"]["relative_std"]  # beyond what the points' readings give it
    assert c["relative_std"] >= moved
    assert any(n.startswith("L: the calibration moves it") for n in cal.notes)
    # a latent in arbitrary units (an encoder's) is not a reading of the same constant
    assert plain.constants["L"]["relative_std"] < moved and not plain.notes
