"""Calibration: known values of a state at known times -> constants in physical units.

The encoder fixes the latent only up to a scale and an offset. Given two or more known values
of a state (`--calibrate "h(0)=0.07; h(25)=0.01"`, times in seconds of the video at the real
frame rate, as latent.png's time axis shows them), fitode

1. fits the affine map x = a*z + b from the best run's encoded latent z (a quadratic through
   the frames within three of each time: see local_value; for a measured path fitted directly,
   through its fitted trajectory there: see point_readings) to the known values, by least
   squares, per calibrated state;
2. maps each constant through it: reading a state x as a*x, the equation holds again with each
   constant c times a**p, the power p found from the equation itself
   (fitode.eqparse.identify.scale_exponents: free fall's g has p = 1, h' = -k*sqrt(h)'s k has
   p = 1/2, a frequency p = 0). For an equation linear in its state that is exact, so the
   calibrated constant is the latent one times the map's scale, whatever a fit would say;
3. checks it: the calibrated trajectory is fitted again (fitode.train.trajectory, windows of the
   training length, from the mapped values). Where the fit and the mapping disagree by more than
   max(AGREE, SIGMAS standard errors), that is a finding naming both numbers, not a silent change.

Constants with no pure power (the pendulum's L under a rescaled angle) or whose equation is not
free of the map's offset take the fitted value instead (from a search over powers of the scale).
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np

from fitode.errors import FitodeError
from fitode.names import finite_number


class CalibrationError(FitodeError):
    """A --calibrate text that cannot be used (one-line message)."""


@dataclass(frozen=True)
class CalibrationPoint:
    state: str
    time: float
    value: float
    std: float = 0.0  # the value's uncertainty as given (h(0)=0.07±0.002), one standard deviation


@dataclass
class AffineMap:
    """x = a*z + b for one state; rms is the residual at the points (0 for exactly two)."""

    a: float
    b: float
    n_points: int
    rms: float = 0.0


_ITEM = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(\'*)\s*\(\s*([^()]*?)\s*\)\s*=\s*(.+?)\s*$")


_PLUS_MINUS = re.compile(r"\s*(?:±|\+-|\+/-)\s*")


def parse_calibration(text: str, states: Sequence[str]) -> list[CalibrationPoint]:
    """'h(0)=0.07; h(25)=0.01' -> points; a value may carry its uncertainty, one standard
    deviation: 'h(0)=0.07±0.002' (or +- or +/-). Strict: known states, numbers, two points per state."""
    if text is None or not str(text).strip():
        raise CalibrationError("--calibrate is empty; give known values like \"h(0)=0.07; h(25)=0.01\"")
    points: list[CalibrationPoint] = []
    for raw in re.split(r"[;\n]", str(text)):
        if not raw.strip():
            continue
        m = _ITEM.match(raw)
        if not m:
            raise CalibrationError(f"--calibrate: cannot read {raw.strip()!r}; write STATE(TIME)=VALUE, "
                                   "for example h(0)=0.07, with items separated by ';'")
        name, primes, t_text, v_text = m.groups()
        if primes:
            raise CalibrationError(f"--calibrate: {name}{primes}(...) gives a derivative; give values of the "
                                   "state itself")
        if name not in states:
            raise CalibrationError(f"--calibrate: {name} is not a state of the equation "
                                   f"(states: {', '.join(states)})")
        t = _number(t_text, f"the time in {raw.strip()!r}")
        v_text, _, s_text = _PLUS_MINUS.sub("\0", v_text).partition("\0")
        v = _number(v_text, f"the value in {raw.strip()!r}")
        sd = _number(s_text, f"the uncertainty in {raw.strip()!r}") if s_text.strip() else 0.0
        if sd < 0:
            raise CalibrationError(f"--calibrate: the uncertainty in {raw.strip()!r} is negative")
        points.append(CalibrationPoint(name, t, v, sd))
    if not points:
        raise CalibrationError("--calibrate has no STATE(TIME)=VALUE item")
    for state in sorted({p.state for p in points}):
        mine = [p for p in points if p.state == state]
        if len({p.time for p in mine}) < 2:
            raise CalibrationError(f"--calibrate: {state} needs known values at two or more different times "
                                   f"(got {len(mine)})")
        if len({p.value for p in mine}) < 2:
            raise CalibrationError(f"--calibrate: the values of {state} are all equal; a scale needs two "
                                   "different values")
    return points


def _number(text: str, what: str) -> float:
    return finite_number(text, f"--calibrate: {what} is not a number", f"--calibrate: {what} is not finite",
                         CalibrationError)


def check_times(points: Sequence[CalibrationPoint], t_first: float, t_last: float | None = None,
                slack: float = 0.0) -> None:
    """Every time must lie within the clip: [t_first, t_last] seconds (t_last None: [0, t_first]),
    give or take `slack` (half a frame: a time typed rounded, 1.017 for a last frame at 1.01667 s,
    still names that frame; it reads the nearest frame's value)."""
    if t_last is None:
        t_first, t_last = 0.0, t_first
    for p in points:
        if not (t_first - slack - 1e-9 <= p.time <= t_last + slack + 1e-9):
            raise CalibrationError(f"--calibrate: {p.state}({p.time:g}) is outside the clip, which runs from "
                                   f"{t_first:.4g} s to {t_last:.4g} s")


def point_readings(points: Sequence[CalibrationPoint], time: np.ndarray, latent: np.ndarray,
                   state: str, states: Sequence[str], fitted: np.ndarray | None = None) -> np.ndarray:
    """The latent z at each of the state's points (in their order): local_value of the fitted
    trajectory where one was fitted to the measured path and covers the point's frames (fitted:
    (T, k), NaN outside its stretch or pieces), else of the latent itself. A measured reading errs
    slowly, and a few frames at a point carry that error into the whole scale (a generated drain's
    level, read 0.2 px RMS off over a travel of 22 px: the two ends' local readings made the scale
    5% large and k +5.7% TRUSTED, where the trajectory through every frame gave it within 0.03%
    and k +0.1%)."""
    time = np.asarray(time, dtype=float)
    col = list(states).index(state)
    raw = np.asarray(latent, dtype=float)[:, col]
    on = on_trajectory(points, time, fitted, state, states)
    smooth = raw if fitted is None else np.asarray(fitted, dtype=float)[:, col]
    mine = [p for p in points if p.state == state]
    return np.array([local_value(time, smooth if o else raw, p.time) for p, o in zip(mine, on)])


def on_trajectory(points: Sequence[CalibrationPoint], time: np.ndarray, fitted: np.ndarray | None, state: str,
                  states: Sequence[str]) -> list[bool]:
    """Whether each of the state's points is read on the fitted trajectory (point_readings): it
    covers every frame the point's local quadratic takes."""
    mine = [p for p in points if p.state == state]
    if fitted is None:
        return [False] * len(mine)
    column = np.asarray(fitted, dtype=float)[:, list(states).index(state)]
    out = []
    for p in mine:
        i = int(np.clip(np.searchsorted(time, p.time), 0, len(time) - 1))
        out.append(bool(np.all(np.isfinite(column[max(0, i - LOCAL_HALF_WIDTH):i + LOCAL_HALF_WIDTH + 1]))))
    return out


def fit_affine(points: Sequence[CalibrationPoint], time: np.ndarray, latent: np.ndarray,
               states: Sequence[str], fitted: np.ndarray | None = None) -> dict[str, AffineMap]:
    """Least-squares x = a*z + b per calibrated state, z read at the points' times (point_readings)."""
    time = np.asarray(time, dtype=float)
    maps: dict[str, AffineMap] = {}
    for state in dict.fromkeys(p.state for p in points):
        col = list(states).index(state)
        mine = [p for p in points if p.state == state]
        z = point_readings(points, time, latent, state, states, fitted)
        v = np.array([p.value for p in mine])
        spread = float(np.ptp(latent[:, col])) or 1.0
        if np.ptp(z) < 1e-6 * spread:
            raise CalibrationError(f"--calibrate: the encoded {state} hardly changes between the given times, "
                                   "so no scale can be read from them; choose times where it differs")
        A = np.stack([z, np.ones_like(z)], axis=1)
        (a, b), *_ = np.linalg.lstsq(A, v, rcond=None)
        rms = float(np.sqrt(np.mean((A @ np.array([a, b]) - v) ** 2)))
        maps[state] = AffineMap(float(a), float(b), len(mine), rms)
    return maps


def scale_uncertainty(points: Sequence[CalibrationPoint], time: np.ndarray, latent: np.ndarray,
                      states: Sequence[str], maps: Mapping[str, AffineMap],
                      fitted: np.ndarray | None = None,
                      moves: Mapping[str, np.ndarray] | None = None) -> dict[str, float]:
    """The relative standard deviation of each map's scale a: from the points' uncertainties
    (the least-squares a is linear in the values, so its variance is the values' variances
    carried through the fit's weights), and from the latent's own reading at the points (the
    local quadratic's standard error there, local_std: a noisy measured latent at a clip's end,
    where points are usually put, moves the whole scale; the fall's 30 frames: 2.5%), carried
    through a's derivative with respect to each reading. moves: {state: (N, points)} how far its
    points' readings on the fitted trajectory move over the bootstrap of the path (_point_moves),
    whose spread of a is taken instead for that state."""
    time = np.asarray(time, dtype=float)
    out: dict[str, float] = {}
    for state, m in maps.items():
        col = list(states).index(state)
        column = np.asarray(latent, dtype=float)[:, col]
        mine = [p for p in points if p.state == state]
        z = point_readings(points, time, latent, state, states, fitted)
        values = np.array([p.value for p in mine])
        A = np.stack([z, np.ones_like(z)], axis=1)
        weights = np.linalg.pinv(A)[0]  # a = weights @ values
        var = float(np.sum((weights * np.array([p.std for p in mine])) ** 2))
        if moves and state in moves:
            a = [float(np.linalg.pinv(np.stack([z + d, np.ones_like(z)], axis=1))[0] @ values) for d in moves[state]]
            out[state] = math.sqrt(var + float(np.var(a, ddof=1))) / abs(m.a) if m.a else math.inf
            continue
        for i, p in enumerate(mine):
            sd = local_std(time, column, p.time)
            if sd > 0:
                moved = z.copy()
                moved[i] += sd
                a = float(np.linalg.pinv(np.stack([moved, np.ones_like(z)], axis=1))[0] @ values)
                var += (a - m.a) ** 2
        out[state] = math.sqrt(var) / abs(m.a) if m.a else math.inf
    return out


LOCAL_HALF_WIDTH = 3


def local_value(time: np.ndarray, z: np.ndarray, at: float) -> float:
    """The latent at time `at` from a quadratic fitted to the frames within LOCAL_HALF_WIDTH
    frames of it (fewer at the clip's ends), not from the one or two frames around it: a
    measured latent is noisiest at the ends of a clip, where calibration points are usually
    put (a falling ball's radius at its smallest), and a single frame's error there sets the
    whole scale."""
    n = len(time)
    if n < 2 * LOCAL_HALF_WIDTH + 1:
        return float(np.interp(at, time, z))
    i = int(np.clip(np.searchsorted(time, at), 0, n - 1))
    lo = max(0, i - LOCAL_HALF_WIDTH)
    hi = min(n, i + LOCAL_HALF_WIDTH + 1)
    t, y = time[lo:hi], z[lo:hi]
    if len(t) < 4 or not np.all(np.isfinite(y)):
        return float(np.interp(at, time, z))
    centre = t.mean()
    coef = np.polyfit(t - centre, y, 2)
    return float(np.polyval(coef, at - centre))


def local_std(time: np.ndarray, z: np.ndarray, at: float) -> float:
    """The standard error of local_value: the quadratic's leverage at `at` times the latent's
    scatter about a quadratic over twice as many frames (a few more degrees of freedom than
    the reading's own seven frames leave); 0 where the clip is too short to tell."""
    n = len(time)
    if n < 4 * LOCAL_HALF_WIDTH + 1 or not np.all(np.isfinite(z)):
        return 0.0
    i = int(np.clip(np.searchsorted(time, at), 0, n - 1))
    lo, hi = max(0, i - LOCAL_HALF_WIDTH), min(n, i + LOCAL_HALF_WIDTH + 1)
    centre = time[lo:hi].mean()
    design = np.vander(time[lo:hi] - centre, 3)
    x0 = np.vander(np.array([at - centre]), 3)[0]
    leverage = float(x0 @ np.linalg.pinv(design.T @ design) @ x0)
    lo, hi = max(0, i - 2 * LOCAL_HALF_WIDTH), min(n, i + 2 * LOCAL_HALF_WIDTH + 1)
    tw, zw = time[lo:hi] - time[lo:hi].mean(), z[lo:hi]
    resid = zw - np.polyval(np.polyfit(tw, zw, 2), tw)
    scatter = math.sqrt(float(resid @ resid) / max(len(tw) - 3, 1))
    return scatter * math.sqrt(max(leverage, 0.0))


@dataclass
class Calibration:
    """A calibration applied to a fit: the maps, the constants before and after, the trajectories."""

    points: list[CalibrationPoint]
    maps: dict[str, AffineMap]
    # name -> before, after, std_after, change, converted, scale; mapped (None without a pure
    # power), refit and refit_std (the fit of the calibrated trajectory), best_run_before
    constants: dict[str, dict[str, Any]]
    latent: np.ndarray  # (T, d) calibrated latent (uncalibrated states unchanged)
    rollout: np.ndarray  # (T, d) physics rollout with the converted constants
    loss: float
    time_offset: float = 0.0
    notes: list[str] = field(default_factory=list)
    on_trajectory: list[bool] = field(default_factory=list)  # per point: read on the fitted trajectory

    def ylabels(self, states: Sequence[str]) -> list[str]:
        """Plot axis labels: a calibrated state is in the units its --calibrate values were given in."""
        from fitode.plots import latent_label
        return [f"{s}\ncalibrated (units of --calibrate)" if s in self.maps else latent_label(s)
                for s in states]

    def converted_names(self) -> list[str]:
        """Constants now in the units of the calibration."""
        return [n for n, c in self.constants.items() if c["converted"]]

    def gauge_fixed_names(self) -> list[str]:
        """Constants whose value is the fit of the calibrated path itself (_fixes_zero): their
        interval comes from that path and the restarts' spread is no part of it."""
        return [n for n, c in self.constants.items() if c.get("gauge_fixed")]

    def findings(self, params: Mapping[str, Any]):
        """Verdict findings: a calibrated constant outside the bounds its equation file declares
        (g < 0 for a fall) is not a physical answer. Two calibration points fix the map exactly, so
        they cannot reveal a bad fit themselves; the bounds can. And a constant whose fit on the
        calibrated trajectory disagrees with the latent value mapped through the calibration is
        ambiguous: the latent does not follow the calibrated state as the equation says."""
        from fitode.train.findings import Finding
        out = []
        for name in self.converted_names():
            v, spec = self.constants[name]["after"], params.get(name)
            lo, hi = (spec.min, spec.max) if spec is not None else (None, None)
            if (lo is not None and not v > lo) or (hi is not None and not v < hi):
                out.append(Finding("not trustworthy", f"calibrated {name} = {v:.4g} lies outside its bounds "
                                   f"({'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}): "
                                   "the latent does not follow the calibrated state"))
        for name, c in self.constants.items():
            if c.get("unfitted"):
                out.append(Finding("not trustworthy", f"calibrated {name}: the equation cannot reproduce the calibrated "
                                   "trajectory from any starting point (it leaves the equation's domain), so "
                                   f"{name} stays in latent units; check the calibration's times and values", (name,)))
            if disagree(c):
                out.append(Finding("ambiguous", f"calibrated {name}: the latent value mapped through the calibration "
                                   f"gives {c['mapped_best']:.6g}, but a fit of the calibrated trajectory gives "
                                   f"{c['refit']:.6g} +- {c['refit_std']:.2g} ({_change(c['refit'], c['mapped_best'])}): "
                                   "the latent does not follow the calibrated state as the equation says (check "
                                   "the calibration's times and values, and the map's offset)", (name,)))
        return out

    def lines(self) -> list[str]:
        out = ["calibration: " + "; ".join(f"{s} = {m.a:.6g}*latent + {m.b:.6g}"
                                            + (f" (rms {m.rms:.3g} over {m.n_points} points)" if m.n_points > 2 else "")
                                            for s, m in self.maps.items())
                            + (" (the points read on the fitted trajectory)" if self.on_trajectory
                               and all(self.on_trajectory) else "")]
        for name, c in self.constants.items():
            if c["converted"]:
                how = "mapped" if c["mapped"] is not None else "fitted"
                out.append(f"  {name}: {c['before']:.6g} (latent units) -> {c['after']:.6g} (calibrated, "
                           f"x{_ratio(c['after'], c['before'])}, {how}; a fit of the calibrated trajectory gives "
                           f"{c['refit']:.6g})")
            elif c.get("unfitted"):
                out.append(f"  {name}: {c['before']:.6g} kept in latent units: the calibrated trajectory could not be "
                           "fitted")
            else:
                out.append(f"  {name}: {c['before']:.6g} kept (scale-free); check: re-fitting the best run's "
                           f"calibrated trajectory moves it {c['best_run_before']:.6g} -> {c['refit']:.6g} "
                           f"({_change(c['refit'], c['best_run_before'])})")
        out += [f"  note: {n}" for n in self.notes]
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "points": [{"state": p.state, "time": p.time, "value": p.value, "std": p.std,
                        "read_on": "the fitted trajectory" if on else "the latent"}
                       for p, on in zip(self.points, self.on_trajectory or [False] * len(self.points))],
            "maps": {s: {"a": m.a, "b": m.b, "n_points": m.n_points, "rms": m.rms} for s, m in self.maps.items()},
            "constants": self.constants,
            "refit_loss": self.loss,
            "method": "affine map x = a*z + b by least squares; each constant mapped by the power of the "
                      "scale under which the equation holds again (fitted to windows of x(t) where no pure "
                      "power exists), and checked by a fit of the calibrated trajectory",
            "notes": self.notes,
        }


def _ratio(after: float, before: float) -> str:
    return f"{after / before:.4g}" if before else "inf"


def _change(after: float, before: float) -> str:
    if before == 0:
        return f"{after - before:+.3g}"
    return f"{100 * (after - before) / abs(before):+.2f}%"


AGREE = 0.01  # a fit of the calibrated trajectory within this of the mapped value agrees with it
SIGMAS = 3.0  # ... or within this many of its standard errors
OFFSET_TOL = 1e-3  # a map's offset this small, relative to the calibrated range, changes no constant


def disagree(c: Mapping[str, Any]) -> bool:
    """Does the fit of the calibrated trajectory disagree with the mapped latent value?"""
    mapped, refit = c.get("mapped_best"), c.get("refit")
    if mapped is None or refit is None or not math.isfinite(refit):
        return False
    return abs(refit - mapped) > max(AGREE * abs(mapped), SIGMAS * c.get("refit_std", 0.0))


def calibrate_result(result, system, params: Mapping[str, Any], points: Sequence[CalibrationPoint],
                     analysis: Mapping[str, Any] | None = None, *, time_offset: float = 0.0,
                     seed: int = 0) -> Calibration:
    """Apply a calibration to a FitResult (its best run's latent) for the equation `system`.

    time_offset: the video time of frame 0 (the points' times are video times).
    """
    time = np.asarray(result.time, dtype=float) + time_offset
    check_times(points, float(time[0]), float(time[-1]), slack=0.5 * float(result.dt))
    latent = np.asarray(result.latent, dtype=float)
    # the run's own fitted trajectory (its stretch, each of its pieces, nothing outside them)
    fitted_path = np.asarray(result.rollout, dtype=float) if result.rollout is not None else None
    if fitted_path is not None and fitted_path.shape != latent.shape:
        fitted_path = None
    # a measured path fitted directly is read at the points on its trajectory (point_readings); an
    # encoder's latent, trained to follow its windows' trajectories, as it is
    on_path = fitted_path if result.meta.get("direct") else None
    maps = fit_affine(points, time, latent, result.states, on_path)
    x = _mapped(latent, maps, result.states)
    best = next(r for r in result.runs if r.index == result.best).final
    settings = result.settings
    options = {"integrator": str(settings.get("integrator", "rk4")), "substeps": int(settings.get("substeps", 1)),
               "windows": int(settings.get("window", 20))}
    if result.meta.get("direct"):
        # a measured path fitted as one trajectory is checked as one: short windows of a noisy
        # path (a 2-pixel ball) start from noisy slopes and pull an acceleration down
        from fitode.train.trajectory import long_options
        options = {**options, "windows": None, **long_options(len(latent))}
    factors = map_factors(system, maps, x, result.states)
    from fitode.eqparse.identify import scale_exponents
    powers = scale_exponents(system)
    scales = {n: _scale(analysis, n) for n in system.learnable}
    mapped_best = {n: best[n] * f for n, f in factors.items() if f is not None}
    # the frames the constants came from: the stretch one trajectory explains, where one was fitted
    stretch = result.meta.get("stretch") or {}
    first, last = int(stretch.get("start_frame", 0)), int(stretch.get("end_frame", result.train_frames))
    fitted = _refit(system, params, x[first:last], result.dt, best, mapped_best, maps, options, seed)
    trajectory = result.meta.get("trajectory") if isinstance(result.meta.get("trajectory"), Mapping) else {}
    moves = _point_moves(system, params, points, time, x, (first, last), result.dt, fitted, maps, on_path,
                         result.states, options, seed) if not trajectory.get("pieces") else None
    rel_a = scale_uncertainty(points, time, latent, result.states, maps, on_path,
                              moves.readings if moves is not None else None)
    measured = _scale_powers(system, params, x[first:last], result.dt, fitted, maps, options, powers)
    reading = _reading_share(system, params, points, time, latent, result.states, maps, fitted, (first, last),
                             result.dt, options, [n for n, f in factors.items() if f is None], on_path, moves)
    constants: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    zeroed = _fixes_zero(result, system, maps, x, fitted)
    if fitted is None:
        notes.append("the calibrated trajectory could not be fitted again, so the mapped constants are unchecked")
    for name in system.learnable:
        est, factor = result.parameters[name], factors[name]
        ref = best.get(name, est.value)
        refit = fitted.values[name] if fitted is not None else math.nan
        converted = scales[name] != "free" if scales[name] else not (factor is not None and factor == 1.0)
        # no mapping and no fit: the constant stays in latent units, and the finding says why
        unfitted = converted and factor is None and fitted is None
        converted = converted and not unfitted
        if not converted:
            after, ratio = est.value, 1.0
        elif factor is not None:
            after, ratio = est.value * factor, factor
        else:
            after, ratio = refit, (refit / ref if ref else math.nan)
        constants[name] = {"before": est.value, "after": after, "std_after": est.std * abs(ratio),
                           "mapped": None if factor is None else est.value * factor,
                           "mapped_best": mapped_best.get(name), "refit": refit,
                           "refit_std": fitted.errors[name] if fitted is not None else math.nan,
                           "best_run_before": ref, "converted": converted, "unfitted": unfitted,
                           "gauge_fixed": zeroed and converted and factor is None, "scale": scales[name],
                           "change": _rel(after, est.value),
                           "relative_std": math.hypot(_relative_std(name, maps, rel_a, powers, measured),
                                                      reading.get(name, 0.0))}
        moved = _moved_share(constants[name], maps, bool(result.meta.get("direct")))
        if moved > constants[name]["relative_std"]:
            notes.append(f"{name}: the calibration moves it {100 * constants[name]['change']:+.2f}% from the measured "
                         f"{est.value:.6g}, though its map rescales the reading by only "
                         f"{_rescale(maps):.2f}%: the reading and the calibration disagree (on the zero, or on "
                         "how the reading bends), and the interval carries the difference")
            constants[name]["relative_std"] = math.hypot(constants[name]["relative_std"], moved)
    best_after = {n: mapped_best.get(n, fitted.values[n] if fitted is not None else best[n]) for n in system.learnable}
    # the run's own fitted trajectory, mapped as its path is: a rollout from the clip's first frames
    # ran a held pendulum's swing 0.2 rad off its data in track.csv, and a dropped ball's through the floor
    if fitted_path is not None:
        rollout = _mapped(fitted_path, maps, result.states)
    else:
        rollout = _rollout(system, params, x, result.dt, best_after, settings)
    loss = fitted.misfit ** 2 if fitted is not None else math.nan
    states = list(result.states)
    read = {s: iter(on_trajectory(points, time, on_path, s, states)) for s in maps}
    return Calibration(list(points), maps, constants, x, rollout, loss, time_offset, notes,
                       [next(read[p.state]) for p in points])


def _fixes_zero(result, system, maps: Mapping[str, AffineMap], x: np.ndarray, fitted) -> bool:
    """Whether the fit of the calibrated path is the estimate itself, and not a check of it: a
    measured path fitted directly (one path, the same for every restart, on one stretch) whose
    map sets the zero of a state the equation reads (h' = -k*sqrt(h)). Such a path is fitted with
    its zero free, and a slow drain's restarts found k 0.136 to 0.175 at one loss, each with a zero
    of its own (a level moving 5 pixels bends too little to tell them apart); the two points fix
    the zero, and the fit of the path they calibrate gave k 0.9% from the truth with +-1.7% (a
    generated drain of the coverage bench), where the restarts' spread made it +-44%."""
    trajectory = result.meta.get("trajectory") if isinstance(result.meta.get("trajectory"), Mapping) else {}
    if fitted is None or not result.meta.get("direct") or trajectory.get("pieces"):
        return False
    return any(_offset_matters(system, s, m, x[:, list(result.states).index(s)]) for s, m in maps.items())


def _offset_matters(system, state: str, m: AffineMap, column: np.ndarray) -> bool:
    """Whether the map's offset moves constants: the equation reads the state's value (not only
    its derivatives) and the offset is beyond OFFSET_TOL of the calibrated column's range."""
    from fitode.eqparse.system import deriv_symbol

    reads = any(rhs.has(deriv_symbol(state, 0)) for rhs in system.rhs.values())
    return reads and abs(m.b) > OFFSET_TOL * max(float(np.max(np.abs(column))), 1e-300)


NEAR_ONE = 0.1  # a map whose scale is within this of 1 (either sign) calibrates a reading already in its units


def _moved_share(c: Mapping[str, Any], maps: Mapping[str, AffineMap], measured: bool) -> float:
    """How far, relative, a calibration moves a constant of a measured path (fitted directly)
    whose reading is already in the calibration's units (every map's scale within NEAR_ONE of 1:
    an angle in radians calibrated by two angles): two readings of the same constant that differ,
    either of which may be the truth, so the difference is an uncertainty of the calibrated value
    (a generated 39-degree swing: the measured angles gave L 0.05% off, two exact angles moved
    it +0.72% with an interval of +-0.08%: a reading that bends by 4 mrad and a zero 2 mrad off,
    which the measured fit refines and the calibration's two points fix). 0 otherwise."""
    if not measured or not c.get("converted") or not maps or _rescale(maps) > 100 * NEAR_ONE:
        return 0.0
    after, before = c.get("after"), c.get("before")
    if after is None or before is None or not (math.isfinite(after) and math.isfinite(before)) or after == 0:
        return 0.0
    return abs(after - before) / abs(after)


def _rescale(maps: Mapping[str, AffineMap]) -> float:
    """The largest change of scale the maps make, in percent."""
    return 100 * max(abs(abs(m.a) - 1.0) for m in maps.values())


def _mapped(path: np.ndarray, maps: Mapping[str, AffineMap], states: Sequence[str]) -> np.ndarray:
    """path (T, k) with each mapped state's column through its map; the others as they are."""
    out = path.copy()
    for s, m in maps.items():
        col = list(states).index(s)
        out[:, col] = m.a * path[:, col] + m.b
    return out


def map_factors(system, maps: Mapping[str, AffineMap], x: np.ndarray, states: Sequence[str]) -> dict[str, float | None]:
    """What each constant is multiplied by when the latent is read through the maps: prod a**p
    over the calibrated states (scale_exponents' powers p; a negative a keeps its sign for an odd
    power). None where no pure power exists, where a negative scale meets a fractional power, or
    where the map's offset is not negligible for a state whose equation reads its value (then
    the offset moves constants too, and only a fit can tell)."""

    from fitode.eqparse.identify import scale_exponents

    powers = scale_exponents(system)
    factors: dict[str, float | None] = {}
    for name in system.learnable:
        exps = powers.get(name)
        factor: float | None = 1.0
        for s, m in maps.items():
            p = None if exps is None else exps.get(s, 0.0)
            if p == 0.0:
                continue
            if p is None or _offset_matters(system, s, m, x[:, list(states).index(s)]) or (m.a < 0 and p != int(p)):
                factor = None
                break
            factor *= abs(m.a) ** p * (-1.0 if m.a < 0 and int(p) % 2 else 1.0)
        factors[name] = factor
    return factors


REFIT_STARTS = 6  # the most ranked starts the fit of the calibrated trajectory tries


def _refit(system, params, x: np.ndarray, dt: float, best: Mapping[str, float], mapped: Mapping[str, float],
           maps: Mapping[str, AffineMap], options: Mapping[str, Any], seed: int):
    """The fit of the calibrated trajectory (fitode.train.trajectory, windows), from the mapped
    values; a constant with no mapping starts from the best of a search over powers of the
    maps' scale (and signs, for a map that flips), and the fit is kept from the best two."""
    from fitode.train.trajectory import fit_trajectory, trajectory_misfit

    names = [n for n in system.learnable if n not in mapped]
    scale = math.exp(np.mean([math.log(abs(m.a)) for m in maps.values()]))
    signs = [1.0, -1.0] if any(m.a < 0 for m in maps.values()) else [1.0]
    powers = [-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0]
    combos = list(itertools.product(*[[s * scale ** p for p in powers for s in signs] for _ in names]))
    if len(combos) > 600:  # many constants without a mapping: a seeded sample of the grid
        rng = np.random.default_rng(seed)
        keep = rng.choice(len(combos), 599, replace=False)
        combos = [tuple(1.0 for _ in names)] + [combos[i] for i in keep]
    starts = [{**dict(mapped), **{n: float(best[n]) * m for n, m in zip(names, combo)}} for combo in combos]
    if len(starts) > 1:
        # the starts are ranked on windows (a direct fit's segments): cheap, and a far start still rolls out
        ranking = {"integrator": options["integrator"], "substeps": options["substeps"],
                   "windows": options.get("windows") or options.get("segments")}
        scored = sorted(((trajectory_misfit(system, params, x, dt, v, **ranking), i) for i, v in enumerate(starts)))
        starts = [starts[i] for v, i in scored if math.isfinite(v)]
    # the best two fits, going down the ranking past starts whose fit fails: a bounded constant
    # started 2.6x below the truth (the drain's k from the windows' best start) can step out of the
    # equation's domain where the next start converges, and then the constant stayed in latent units
    fits = []
    for v in starts[:REFIT_STARTS]:
        f = fit_trajectory(system, params, x, dt, v, **options)
        if f is not None:
            fits.append(f)
            if len(fits) == 2:
                break
    return min(fits, key=lambda f: f.misfit) if fits else None


SCALE_STEP = 0.01  # the calibrated path scaled by this much to measure a constant's power of the scale


def _scale_powers(system, params, x: np.ndarray, dt: float, fitted, maps: Mapping[str, AffineMap],
                  options: Mapping[str, Any], powers: Mapping[str, Mapping[str, float] | None]) -> dict[str, float]:
    """{name: d log(constant) / d log(scale)} for the constants with no pure power of the one
    map's scale (a large swing's L moves with its amplitude), measured: the calibrated path x
    scaled by SCALE_STEP about zero and fitted again from the fit's values. The power the
    conversion itself showed, log|ratio| / log|a|, is no measure where the map hardly rescales
    (an angle already read in radians: a = 0.99999, so the refit's own 0.05% difference from
    the windows' value read as a power of 50, and L's interval as +-8%). {} where none is needed
    or no fit could be made."""
    from fitode.train.trajectory import fit_trajectory

    names = [n for n in system.learnable if powers.get(n) is None]
    if not names or len(maps) != 1 or fitted is None:
        return {}
    scaled = fit_trajectory(system, params, x * (1.0 + SCALE_STEP), dt, fitted.values, **options)
    if scaled is None:
        return {}
    out = {}
    for n in names:
        a, b = fitted.values[n], scaled.values[n]
        if a and b and a * b > 0:
            out[n] = math.log(b / a) / math.log1p(SCALE_STEP)
    return out


def _reading_share(system, params, points: Sequence[CalibrationPoint], time: np.ndarray, latent: np.ndarray,
                   states: Sequence[str], maps: Mapping[str, AffineMap], fitted, frames: tuple[int, int],
                   dt: float, options: Mapping[str, Any], names: Sequence[str],
                   on_path: np.ndarray | None = None, moves: PointMoves | None = None) -> dict[str, float]:
    """The relative std that the latent's reading at the points gives each constant refitted after
    the map (no pure power: the drain's k, which the map's offset moves as well as its scale).
    Each point's reading is moved by its error, the map fitted again and the calibrated path
    refitted; the changes add in quadrature. A reading's error is what the path's residuals from
    its fitted trajectory average to over the frames the reading averages (local_value), or the
    local quadratic's standard error where larger: a level read with slow errors (0.4 mm over 1 s
    of a generated drain) moves a reading that no scatter about a local quadratic shows, and the
    scale's power alone (k as sqrt(a)) misses that a point moved turns the map about the other.
    Where the points are read on the fitted trajectory (moves: how far those readings move over the
    bootstrap of the path, _point_moves), each constant's change per moved reading is carried
    through those moves instead, which hang together as the trajectory does."""
    if not names or fitted is None or len(maps) != 1 or fitted.windows is not None:
        return {}
    state, m = next(iter(maps.items()))
    col = list(states).index(state)
    column = np.asarray(latent, dtype=float)[:, col]
    res = np.asarray(fitted.residuals, dtype=float).reshape(len(fitted.residuals), -1)[:, col] / abs(m.a)
    width = 2 * LOCAL_HALF_WIDTH + 1
    if len(res) < 2 * width or not np.all(np.isfinite(res)):
        return {}
    slow = float(np.sqrt(np.mean(np.convolve(res, np.ones(width) / width, mode="valid") ** 2)))
    mine = [p for p in points if p.state == state]
    z = point_readings(points, time, latent, state, states, on_path)
    values = np.array([p.value for p in mine])
    first, last = frames
    from fitode.train.trajectory import fit_trajectory
    steps, shifts = [], []  # each point's reading moved by its error, and each constant's change
    for i, p in enumerate(mine):
        steps.append(max(slow, local_std(time, column, p.time)))
        moved = z.copy()
        moved[i] += steps[-1]
        (a, b), *_ = np.linalg.lstsq(np.stack([moved, np.ones_like(moved)], axis=1), values, rcond=None)
        x = np.asarray(latent, dtype=float).copy()
        x[:, col] = a * column + b
        f = fit_trajectory(system, params, x[first:last], dt, fitted.values, **options)
        if f is None:
            return {}
        shifts.append({n: f.values[n] - fitted.values[n] for n in names})
    drawn = moves.readings.get(state) if moves is not None else None
    if drawn is None:
        var = {n: sum(d[n] ** 2 for d in shifts) for n in names}
    else:
        # the same resampled paths move the constants (the interval's residual share) and the
        # readings: only what the readings add to the constants' own moves is this share's (a
        # steeper trajectory reads a wider map, which takes the refit constant back: the seed-10
        # drains' two parts, added as if apart, made +-1.3-2.3% for errors under 0.1%)
        own = moves.constants
        var = {}
        for n in names:
            carried = sum(d[n] / step * drawn[:, i] for i, (d, step) in enumerate(zip(shifts, steps)))
            var[n] = max(float(np.var(carried + own[n], ddof=1) - np.var(own[n], ddof=1)), 0.0)
    return {n: math.sqrt(var[n]) / abs(fitted.values[n]) for n in names if fitted.values.get(n)}


class PointMoves(NamedTuple):
    """What one bootstrap of the calibrated path moves (_point_moves): {state: (N, points)} each of
    the state's point readings on the fitted trajectory, in the latent's units, and {name: (N,)}
    each constant, in the same refits."""
    readings: dict[str, np.ndarray]
    constants: dict[str, np.ndarray]


def _point_moves(system, params, points: Sequence[CalibrationPoint], time: np.ndarray, x: np.ndarray,
                 frames: tuple[int, int], dt: float, fitted, maps: Mapping[str, AffineMap], on_path: np.ndarray | None,
                 states: Sequence[str], options: Mapping[str, Any], seed: int) -> PointMoves | None:
    """How far the point readings move when they are read on the trajectory fitted to the
    calibrated path x[first:last] (T, k) and that path's residuals are resampled
    (fitode.train.interval.trajectory_moves), for each state whose points are all read on the
    fitted trajectory, and how far the constants move in the same refits. A reading on the
    trajectory averages the reading's slow errors over the whole path, which the frames at a point
    do not (the seed-10 drains: 0.04% off where the frames' share gave +-5.3%). None where there is
    none to make."""
    if on_path is None or fitted is None or fitted.windows is not None:
        return None
    states = list(states)
    mine = [s for s in maps if all(on_trajectory(points, time, on_path, s, states))]
    if not mine:
        return None
    from fitode.train.interval import trajectory_moves
    first, last = frames
    drawn = trajectory_moves(system, params, x[first:last], dt, fitted.values, seed=seed,
                             integrator=options["integrator"], substeps=options["substeps"])
    if drawn is None:
        return None
    _, moved, constants = drawn
    span = np.asarray(time, dtype=float)[first:last]
    readings = {}
    for s in mine:
        col, a = states.index(s), maps[s].a
        at = [p.time for p in points if p.state == s]
        readings[s] = np.array([[local_value(span, d[:, col], t) / a for t in at] for d in moved])
    return PointMoves(readings, constants)


def _relative_std(name: str, maps: Mapping[str, AffineMap], rel_a: Mapping[str, float],
                  powers: Mapping[str, Mapping[str, float] | None], measured: Mapping[str, float]) -> float:
    """The relative standard deviation a calibrated constant takes from the points'
    uncertainties: the constant goes as prod a_s**p_s, so its relative std is the quadrature sum
    of p_s times each scale's; where no pure power exists (a constant fitted after the map), the
    power measured on the calibrated path (_scale_powers), over one map (0 where it cannot tell)."""
    exps = powers.get(name)
    if exps is None:
        if len(maps) != 1 or name not in measured:
            return 0.0
        exps = {next(iter(maps)): measured[name]}
    return float(math.sqrt(sum((exps.get(s, 0.0) * rel_a.get(s, 0.0)) ** 2 for s in maps)))


def _rel(after: float, before: float) -> float:
    return (after - before) / abs(before) if before else math.inf if after != before else 0.0


def _scale(analysis, name: str) -> str | None:
    if not analysis:
        return None
    return (analysis.get("constants", {}).get(name) or {}).get("scale")


def _rollout(system, params, x: np.ndarray, dt: float, values: Mapping[str, float], settings) -> np.ndarray:
    import torch

    from fitode.codegen import PhysicsBlock
    block = PhysicsBlock(system, params, integrator=str(settings.get("integrator", "rk4")),
                         substeps=int(settings.get("substeps", 1)), dtype=torch.float64)
    xt = torch.as_tensor(np.asarray(x, dtype=np.float64))
    try:
        block.set_constants(dict(values))
        with torch.no_grad():
            r = block(xt[None, : block.n_context], xt.shape[0], dt)[0]
        return r.numpy()
    except FitodeError:
        return np.full_like(np.asarray(x, dtype=float), np.nan)
