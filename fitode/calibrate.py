"""Calibration: known values of a state at known times -> constants in physical units.

The encoder fixes the latent only up to a scale and an offset. Given two or more known values
of a state (`--calibrate "h(0)=0.07; h(25)=0.01"`, times in seconds of the video at the real
frame rate, as latent.png's time axis shows them), fitode

1. fits the affine map x = a*z + b from the best run's encoded latent z (a quadratic through
   the frames within three of each time: see local_value) to the known values, by least
   squares, per calibrated state;
2. re-estimates the equation's constants on the calibrated trajectory x(t): windows of x of the
   training length, the physics block rolled out from each window's first frames, only the
   constants learnable (a coarse search over starting points, then Adam, then L-BFGS). This
   works for any equation, however the constants depend on the scale.

Constants the analysis calls scale-free (a decay rate, a frequency) keep their estimate; their
re-fit value is reported as a check and should agree. Every other constant is converted.
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from fitode.errors import FitodeError


class CalibrationError(FitodeError):
    """A --calibrate text that cannot be used (one-line message)."""


@dataclass(frozen=True)
class CalibrationPoint:
    state: str
    time: float
    value: float


@dataclass
class AffineMap:
    """x = a*z + b for one state; rms is the residual at the points (0 for exactly two)."""

    a: float
    b: float
    n_points: int
    rms: float = 0.0


_ITEM = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(\'*)\s*\(\s*([^()]*?)\s*\)\s*=\s*(.+?)\s*$")


def parse_calibration(text: str, states: Sequence[str]) -> list[CalibrationPoint]:
    """'h(0)=0.07; h(25)=0.01' -> points. Strict: known states, numbers, two points per state."""
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
        v = _number(v_text, f"the value in {raw.strip()!r}")
        points.append(CalibrationPoint(name, t, v))
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
    try:
        v = float(text)
    except ValueError:
        raise CalibrationError(f"--calibrate: {what} is not a number") from None
    if not math.isfinite(v):
        raise CalibrationError(f"--calibrate: {what} is not finite")
    return v


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


def fit_affine(points: Sequence[CalibrationPoint], time: np.ndarray, latent: np.ndarray,
               states: Sequence[str]) -> dict[str, AffineMap]:
    """Least-squares x = a*z + b per calibrated state, z interpolated at the points' times."""
    time = np.asarray(time, dtype=float)
    maps: dict[str, AffineMap] = {}
    for state in dict.fromkeys(p.state for p in points):
        col = list(states).index(state)
        mine = [p for p in points if p.state == state]
        z = np.array([local_value(time, np.asarray(latent, dtype=float)[:, col], p.time) for p in mine])
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


@dataclass
class Calibration:
    """A calibration applied to a fit: the maps, the constants before and after, the trajectories."""

    points: list[CalibrationPoint]
    maps: dict[str, AffineMap]
    constants: dict[str, dict[str, Any]]  # name -> before, after, std_after, change, converted, scale, refit
    latent: np.ndarray  # (T, d) calibrated latent (uncalibrated states unchanged)
    rollout: np.ndarray  # (T, d) physics rollout with the converted constants
    loss: float
    time_offset: float = 0.0
    notes: list[str] = field(default_factory=list)

    def ylabels(self, states: Sequence[str]) -> list[str]:
        """Plot axis labels: a calibrated state is in the units its --calibrate values were given in."""
        from fitode.plots import latent_label
        return [f"{s}\ncalibrated (units of --calibrate)" if s in self.maps else latent_label(s)
                for s in states]

    def converted_names(self) -> list[str]:
        """Constants now in the units of the calibration."""
        return [n for n, c in self.constants.items() if c["converted"]]

    def findings(self, params: Mapping[str, Any]):
        """Verdict findings: a calibrated constant outside the bounds its equation file declares
        (g < 0 for a fall) is not a physical answer. Two calibration points fix the map exactly, so
        they cannot reveal a bad fit themselves; the bounds can."""
        from fitode.train.verdict import Finding
        out = []
        for name in self.converted_names():
            v, spec = self.constants[name]["after"], params.get(name)
            lo, hi = (spec.min, spec.max) if spec is not None else (None, None)
            if (lo is not None and not v > lo) or (hi is not None and not v < hi):
                out.append(Finding("not trustworthy", f"calibrated {name} = {v:.4g} lies outside its bounds "
                                   f"({'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}): "
                                   "the latent does not follow the calibrated state"))
        return out

    def lines(self) -> list[str]:
        out = ["calibration: " + "; ".join(f"{s} = {m.a:.6g}*latent + {m.b:.6g}"
                                            + (f" (rms {m.rms:.3g} over {m.n_points} points)" if m.n_points > 2 else "")
                                            for s, m in self.maps.items())]
        for name, c in self.constants.items():
            if c["converted"]:
                out.append(f"  {name}: {c['before']:.6g} (latent units) -> {c['after']:.6g} (calibrated, "
                           f"x{_ratio(c['after'], c['before'])})")
            else:
                out.append(f"  {name}: {c['before']:.6g} kept (scale-free); check: re-fitting the best run's "
                           f"calibrated trajectory moves it {c['best_run_before']:.6g} -> {c['refit']:.6g} "
                           f"({_change(c['refit'], c['best_run_before'])})")
        out += [f"  note: {n}" for n in self.notes]
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "points": [{"state": p.state, "time": p.time, "value": p.value} for p in self.points],
            "maps": {s: {"a": m.a, "b": m.b, "n_points": m.n_points, "rms": m.rms} for s, m in self.maps.items()},
            "constants": self.constants,
            "refit_loss": self.loss,
            "method": "affine map x = a*z + b by least squares; constants re-fitted to windows of x(t) "
                      "with the physics block (scale-free constants kept, their re-fit reported)",
            "notes": self.notes,
        }


def _ratio(after: float, before: float) -> str:
    return f"{after / before:.4g}" if before else "inf"


def _change(after: float, before: float) -> str:
    if before == 0:
        return f"{after - before:+.3g}"
    return f"{100 * (after - before) / abs(before):+.2f}%"


def calibrate_result(result, system, params: Mapping[str, Any], points: Sequence[CalibrationPoint],
                     analysis: Mapping[str, Any] | None = None, *, time_offset: float = 0.0,
                     seed: int = 0) -> Calibration:
    """Apply a calibration to a FitResult (its best run's latent) for the equation `system`.

    time_offset: the video time of frame 0 (the points' times are video times).
    """
    time = np.asarray(result.time, dtype=float) + time_offset
    check_times(points, float(time[0]), float(time[-1]), slack=0.5 * float(result.dt))
    latent = np.asarray(result.latent, dtype=float)
    maps = fit_affine(points, time, latent, result.states)
    x = latent.copy()
    for s, m in maps.items():
        col = result.states.index(s)
        x[:, col] = m.a * latent[:, col] + m.b
    best = next(r for r in result.runs if r.index == result.best).final
    scale = math.exp(np.mean([math.log(abs(m.a)) for m in maps.values()]))
    flip = any(m.a < 0 for m in maps.values())
    settings = result.settings
    scales = {n: _scale(analysis, n) for n in system.learnable}
    refit, loss = refit_constants(
        system, params, x[: result.train_frames], result.dt, start=best, scale=scale, flip=flip,
        scale_free=[n for n, s in scales.items() if s == "free"], window=int(settings.get("window", 20)),
        integrator=str(settings.get("integrator", "rk4")), substeps=int(settings.get("substeps", 1)), seed=seed)
    constants: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    for name in system.learnable:
        est = result.parameters[name]
        converted = scales[name] != "free"
        after = refit[name] if converted else est.value
        ref = best.get(name, est.value)
        std_after = est.std * abs(refit[name] / ref) if converted and ref else est.std
        constants[name] = {"before": est.value, "after": after, "std_after": std_after, "refit": refit[name],
                           "best_run_before": ref, "converted": converted, "scale": scales[name],
                           "change": _rel(after, est.value)}
        if not converted and abs(_rel(refit[name], ref)) > 0.05:
            notes.append(f"{name} is scale-free but its re-fit on the calibrated trajectory moved "
                         f"{_change(refit[name], ref)}: the calibration points may not match the latent "
                         "(check the times and values)")
    rollout = _rollout(system, params, x, result.dt, refit, settings)
    return Calibration(list(points), maps, constants, x, rollout, loss, time_offset, notes)


def _rel(after: float, before: float) -> float:
    return (after - before) / abs(before) if before else math.inf if after != before else 0.0


def _scale(analysis, name: str) -> str | None:
    if not analysis:
        return None
    return (analysis.get("constants", {}).get(name) or {}).get("scale")


# ----------------------------------------------------------------------------- the trajectory fit
def refit_constants(system, params: Mapping[str, Any], x: np.ndarray, dt: float, *, start: Mapping[str, float],
                    scale: float = 1.0, flip: bool = False, scale_free: Sequence[str] = (), window: int = 20,
                    integrator: str = "rk4", substeps: int = 1, steps: int = 150, max_windows: int = 128,
                    seed: int = 0) -> tuple[dict[str, float], float]:
    """Fit the learnable constants so the physics block, rolled out from each window's first
    frames of x (T, d), reproduces the rest of the window. Returns (constants, loss).

    Starting points: `start` with every constant not in scale_free multiplied by scale**p for p in
    -2..2 (and by -1 too when flip: a negative map can flip signs); the best few by loss are refined.
    """
    import torch

    torch.manual_seed(seed)
    make, loss_of, evaluate = _window_problem(system, params, x, dt, window, integrator, substeps, max_windows)
    names = list(system.learnable)
    powers = [-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0]
    signs = [1.0, -1.0] if flip else [1.0]
    choices = [[1.0] if n in scale_free else [s * scale ** p for p in powers for s in signs] for n in names]
    combos = list(itertools.product(*choices))
    if len(combos) > 600:  # many scale-dependent constants: a seeded sample of the grid
        rng = np.random.default_rng(seed)
        keep = rng.choice(len(combos), 599, replace=False)
        combos = [tuple(1.0 for _ in names)] + [combos[i] for i in keep]
    scored = []
    for combo in combos:
        cand = {n: float(start[n]) * m for n, m in zip(names, combo)}
        scored.append((evaluate(cand), cand))
    scored.sort(key=lambda s: s[0])
    finite = [c for v, c in scored if math.isfinite(v)]
    if not finite:
        raise CalibrationError("the equation cannot reproduce the calibrated trajectory from any starting point "
                               "(it leaves the equation's domain); check the calibration values")
    best_vals, best_loss = None, math.inf
    for cand in finite[:2]:
        vals, loss = _refine(make(cand), loss_of, steps)
        if loss < best_loss:
            best_vals, best_loss = vals, loss
    if best_vals is None:
        raise CalibrationError("the re-fit of the constants on the calibrated trajectory did not converge")
    return best_vals, best_loss


def window_loss(system, params: Mapping[str, Any], x: np.ndarray, dt: float, values: Mapping[str, float], *,
                window: int = 20, integrator: str = "rk4", substeps: int = 1, max_windows: int = 128) -> float:
    """The loss refit_constants minimises, for the given constants (inf outside their domain)."""
    return _window_problem(system, params, x, dt, window, integrator, substeps, max_windows)[2](values)


def _window_problem(system, params, x: np.ndarray, dt: float, window: int, integrator: str, substeps: int,
                    max_windows: int):
    """(make, loss_of, evaluate) for fitting constants to windows of the trajectory x (T, d): the
    physics block rolled out from each window's first frames reproduces the rest of the window."""
    import torch

    from fitode.codegen import PhysicsBlock

    xt = torch.as_tensor(np.asarray(x, dtype=np.float64), dtype=torch.float32)
    T = xt.shape[0]
    window = min(window, T)
    n_win = T - window + 1
    if n_win < 1:
        raise CalibrationError("too few frames to re-fit the constants on the calibrated trajectory")
    starts = torch.arange(n_win)
    if n_win > max_windows:
        starts = torch.linspace(0, n_win - 1, max_windows).round().long().unique()
    idx = starts[:, None] + torch.arange(window)[None, :]
    xw = xt[idx]  # (B, L, d)
    weight = 1.0 / xt.var(dim=0).clamp_min(1e-12)  # every state counts equally, whatever its units

    def make(values: Mapping[str, float]) -> PhysicsBlock | None:
        block = PhysicsBlock(system, params, integrator=integrator, substeps=substeps)
        try:
            block.set_constants(dict(values))
        except FitodeError:
            return None
        return block

    def loss_of(block) -> torch.Tensor:
        nc = block.n_context
        pred = block(xw[:, :nc], window, dt)
        return torch.mean(((pred[:, nc:] - xw[:, nc:]) ** 2) * weight)

    def evaluate(values: Mapping[str, float]) -> float:
        block = make(values)
        if block is None:
            return math.inf
        try:
            with torch.no_grad():
                v = float(loss_of(block))
        except (FitodeError, RuntimeError, FloatingPointError):
            return math.inf
        return v if math.isfinite(v) else math.inf

    return make, loss_of, evaluate


def _refine(block, loss_of, steps: int) -> tuple[dict[str, float] | None, float]:
    import torch

    params = [p for p in block.parameters() if p.requires_grad]
    opt = torch.optim.Adam(block.param_groups(lr=0.05))
    best_loss, best_vals = math.inf, None

    def snapshot(loss: float):
        nonlocal best_loss, best_vals
        if math.isfinite(loss) and loss < best_loss:
            best_loss, best_vals = loss, {k: float(v.detach()) for k, v in block.constants().items()}

    for i in range(steps):
        try:
            loss = loss_of(block)
        except (FitodeError, RuntimeError, FloatingPointError):
            break
        if not torch.isfinite(loss):
            break
        snapshot(float(loss.detach()))
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if i == steps // 2:
            for g in opt.param_groups:
                g["lr"] *= 0.1
    if best_vals is not None:  # polish: the loss is smooth in a few constants, L-BFGS lands on the minimum
        block.set_constants(best_vals)
        lbfgs = torch.optim.LBFGS(params, lr=0.5, max_iter=50, line_search_fn="strong_wolfe")

        def closure():
            lbfgs.zero_grad(set_to_none=True)
            value = loss_of(block)
            value.backward()
            return value
        try:
            lbfgs.step(closure)
            with torch.no_grad():
                snapshot(float(loss_of(block)))
        except (FitodeError, RuntimeError, FloatingPointError):
            pass
    return best_vals, best_loss


def _rollout(system, params, x: np.ndarray, dt: float, values: Mapping[str, float], settings) -> np.ndarray:
    import torch

    from fitode.codegen import PhysicsBlock
    block = PhysicsBlock(system, params, integrator=str(settings.get("integrator", "rk4")),
                         substeps=int(settings.get("substeps", 1)))
    block.set_constants(dict(values))
    xt = torch.as_tensor(np.asarray(x), dtype=torch.float32)
    try:
        with torch.no_grad():
            r = block(xt[None, : block.n_context], xt.shape[0], dt)[0]
        return r.double().numpy()
    except FitodeError:
        return np.full_like(np.asarray(x, dtype=float), np.nan)
