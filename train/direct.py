"""A measured path fitted directly: the equation's constants from the trajectory fitter, no encoder.

Where the observation measures the state (a position, a size, a brightness, an angle: one column
per state, affine in it or equal to it), an encoder has nothing to learn but the affine map, and
the trajectory fitter (trajectory.py) finds the constants, the map and the starting state at once,
on one trajectory of the equation over the whole stretch: what acts slowly (light damping, drag)
shows over all of it, which short training windows cannot see.

Every restart of the plan starts from its own constants (trainer.restart_inits): first a fit of
short windows of the path (multiple shooting from the measured frames: a wrong frequency or rate
still lands near the right one, where one long trajectory from it would settle in a far basin);
restarts whose windows agree share the one-trajectory fit that follows (long paths are rolled out
in segments tied together, trajectory.py's segments). So the restart table and the assessment get
runs as from the encoder's training, at a fraction of the time.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from .history import History
from .result import RunRecord
from .trajectory import TrajectoryFit, fit_trajectory, long_options

SCREEN_WINDOWS = 32  # windows the restarts' first fit looks at (evenly spread)
SCREEN_ITERATIONS = 15
SCREEN_FRAMES = 10  # the restarts' windows: short, so that a start far off (a drain 100x too fast) still rolls out
SCALE_FLOOR = 0.01  # a learned scale the windows drive to zero: a small swing, where sin(x) = x to 1e-4
AGREE = 0.02  # restarts whose window fits land this close (relative, every constant) share one full fit
FLIP_GAIN = 2.0
FREE_GAIN = 4.0  # a state's direction is turned where its one trajectory then misfits at most half as much
REFIT_WITHIN = 3.0  # a cluster is fitted in full when its windows misfit is within this factor of the best
AT_BOUND = 1e-6  # a constant this close to its bound (relative to its start's distance) has no slope there
CONTINUE_ITERATIONS = 25  # the steps of a second whole-path fit where the first stopped at its bound (_continued)


@dataclass
class DirectFit:
    """Every restart's record, the fit each one ended with, and the best."""

    records: list[RunRecord]
    fits: list[TrajectoryFit | None]
    best: int


def fit_path(system, params: Mapping, x: np.ndarray, dt: float, inits: Sequence[Mapping[str, float]],
             seeds: Sequence[int], *, gauge: Mapping | None = None, integrator: str = "rk4",
             substeps: int = 1) -> DirectFit:
    """Every restart's constants on the measured path x (T, k), in x's units (gauge: the learned
    scale and offset of each state, fit_trajectory's)."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    opts = {"integrator": integrator, "substeps": substeps, "gauge": gauge}
    screened, clock = [], []
    for init in inits:
        t0 = time.perf_counter()
        screened.append(screen(system, params, x, dt, init, **opts))
        clock.append(time.perf_counter() - t0)
    ok = [i for i, w in enumerate(screened) if w is not None]
    best_screen = min((screened[i].misfit for i in ok), default=math.inf)
    clusters: list[list[int]] = []
    for i in sorted(ok, key=lambda j: screened[j].misfit):
        for c in clusters:
            if _agree(screened[c[0]].values, screened[i].values, system.learnable):
                c.append(i)
                break
        else:
            clusters.append([i])
    fits: list[TrajectoryFit | None] = [None] * len(inits)
    why: dict[int, str] = {}
    for c in clusters:
        lead = screened[c[0]]
        if lead.misfit > REFIT_WITHIN * best_screen:
            for i in c:
                why[i] = (f"its window fit missed the path {lead.misfit / max(best_screen, 1e-300):.1f}x more than the "
                          "best; not fitted further")
            continue
        t0 = time.perf_counter()
        full = full_fit(system, params, x, dt, off_bounds(lead, inits[c[0]], params), **long_options(len(x)), **opts)
        if full is not None and not full.converged:
            full = _continued(system, params, x, dt, full, opts)
        if full is not None and not all(math.isfinite(v) for v in (full.misfit, *full.values.values())):
            full = None  # a path of noise: the fit ran off to no number
        spent = (time.perf_counter() - t0) / len(c)
        for i in c:
            fits[i] = full
            clock[i] += spent
            if full is None:
                why[i] = "one trajectory from its windows' constants leaves the equation's domain"
    records = [_record(i, seeds[i], inits[i], screened[i], fits[i], clock[i], why.get(i), system.learnable,
                       system.states)
               for i in range(len(inits))]
    done = [i for i in range(len(inits)) if fits[i] is not None]
    best = min(done, key=lambda i: fits[i].misfit) if done else 0
    return DirectFit(records, fits, best)


def full_fit(system, params: Mapping, x: np.ndarray, dt: float, lead: TrajectoryFit, *, gauge: Mapping | None,
              **options) -> TrajectoryFit | None:
    """One trajectory over the whole path from the windows' constants. A learned scale stays the
    windows' (at least SCALE_START): over one long trajectory a scale the equation fixes only
    through its nonlinearity (a pendulum's swing read as a position) trades against the
    constants (a swing made 25 degrees to bend the period, L 2.4% off on the real bob clip),
    where short windows keep to what the path shows. The fit's gauge is reported in x's units."""

    learned = {st: g for st, g in (gauge or {}).items() if g is not None and g.scale_learned}
    if not learned:
        return fit_trajectory(system, params, x, dt, lead.values, gauge=gauge, **options)
    scale = np.array([max(float((lead.gauge or {}).get(st, {}).get("scale", SCALE_FLOOR)), SCALE_FLOOR)
                      if st in learned else 1.0 for st in system.states])
    held = {st: (replace(g, scale_learned=False) if st in learned else g) for st, g in gauge.items()}
    full = fit_trajectory(system, params, x * scale, dt, lead.values, gauge=held, **options)
    if full is None:
        return None
    # the windows' scale is wrong where the path bends only over many windows (a fall with drag
    # near its terminal velocity: 1.01 for 1.46, k 0.70 for 0.27); the scale is set free where one
    # trajectory then fits FREE_GAIN times better (a swing trading its scale against L gains little)
    free = fit_trajectory(system, params, x * scale, dt, full.values, gauge=gauge, **options)
    if free is not None and math.isfinite(free.misfit) and free.misfit * FREE_GAIN < full.misfit:
        full = free
    full.residuals = full.residuals / scale
    full.gauge = {st: {"scale": float(scale[i]) * (full.gauge or {}).get(st, {}).get("scale", 1.0),
                       "offset": (full.gauge or {}).get(st, {}).get("offset", 0.0)}
                  for i, st in enumerate(system.states)}
    return full


def _continued(system, params: Mapping, x: np.ndarray, dt: float, full: TrajectoryFit, opts: dict) -> TrajectoryFit:
    """A whole path's fit that stopped at its solver's bound, fitted once more from its constants:
    where the cost still crept down along a valley (a held pendulum's 67 frames, under half its
    period, where L, zeta and the swing trade: 100 steps, 202 rollouts, L 1.8% from the windows'
    fit), the second fit starts afresh beside the minimum and settles in a few steps. Kept where it
    settles and fits as well; else the first, unsettled, as it was. Within CONTINUE_ITERATIONS: a
    drain's fit that creeps on from there too (seed 1's drains: the same k to 1e-5) costs a quarter
    of the first, not all of it again."""
    again = full_fit(system, params, x, dt, full, iterations=CONTINUE_ITERATIONS, **long_options(len(x)), **opts)
    if again is not None and again.converged and math.isfinite(again.misfit) and again.misfit <= full.misfit * (1 + 1e-6):
        return again
    return full


def off_bounds(lead: TrajectoryFit, init: Mapping[str, float], params: Mapping) -> TrajectoryFit:
    """The windows' fit with every constant they drove onto a bound (a damping short windows cannot
    see, sent to its minimum 0) started again from the restart's own value: a bounded constant is
    read through exp (fitode.codegen.constants), so at 1e-24 above its bound it has no slope, and
    one trajectory from there keeps it (a decaying swing fitted with zeta 1e-24, misfit 5.7x that
    from zeta 0.05, which finds zeta 0.090 for 0.093)."""
    values = dict(lead.values)
    for name, v in lead.values.items():
        spec = params.get(name)
        if spec is None or name not in init:
            continue
        start = float(init[name])
        for bound in (spec.min, spec.max):
            if bound is not None and abs(v - bound) <= AT_BOUND * max(abs(start - bound), 1e-300):
                values[name] = start
    return lead if values == lead.values else replace(lead, values=values)


def orientation(system, params: Mapping, x: np.ndarray, dt: float, start: Mapping[str, float], *,
                gauge: Mapping | None = None, **options) -> np.ndarray:
    """(k,) +1 or -1 per column of the measured path x (T, k): the direction in which each state
    whose scale the equation fixes (a learned scale, which stays positive) runs along its column.
    The reader's axes are its own (y up), the equation's the user's: a fall written as
    y'' = g - k*y'*abs(y') runs down, and read up its one trajectory has no positive scale (the
    generated drag fall: k -0.003 for 0.272). Each combination of directions is screened; a flip
    is taken only where it fits at least FLIP_GAIN times better (a swing is the same both ways)."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    learned = [i for i, st in enumerate(system.states) if (gauge or {}).get(st) is not None and gauge[st].scale_learned]
    signs = np.ones(x.shape[1])
    if not learned or len(learned) > 2 or x.shape[1] != len(system.states):
        return signs
    # one trajectory over the whole path: short windows fit either direction (a parabola each)
    options = {**options, **long_options(len(x))}
    best = fit_trajectory(system, params, x, dt, start, gauge=gauge, **options)
    for combo in range(1, 2 ** len(learned)):
        trial = np.ones(x.shape[1])
        for bit, i in enumerate(learned):
            if combo >> bit & 1:
                trial[i] = -1.0
        got = fit_trajectory(system, params, x * trial, dt, start, gauge=gauge, **options)
        if got is not None and (best is None or got.misfit * FLIP_GAIN < best.misfit):
            best, signs = got, trial
    return signs


def screen(system, params: Mapping, x: np.ndarray, dt: float, start: Mapping[str, float],
           **options) -> TrajectoryFit | None:
    """The constants of short windows of x (multiple shooting from the measured frames), from
    `start`: a cheap first fit that lands near the right basin from far away."""
    # SCREEN_FRAMES whatever the training window: a 5-frame window is shorter than a second-order
    # block's context (the real bouncing ball's 11 frames failed every restart when it took that)
    n = min(SCREEN_FRAMES, len(x))
    return fit_trajectory(system, params, x, dt, start, windows=n, max_windows=SCREEN_WINDOWS,
                          iterations=SCREEN_ITERATIONS, solver="lm", **options)


def _agree(a: Mapping[str, float], b: Mapping[str, float], names: Sequence[str]) -> bool:
    return all(abs(a[n] - b[n]) <= AGREE * max(abs(a[n]), abs(b[n]), 1e-12) for n in names)


def _record(index: int, seed: int, init: Mapping[str, float], screen: TrajectoryFit | None,
            full: TrajectoryFit | None, wall: float, why: str | None, names: Sequence[str],
            states: Sequence[str]) -> RunRecord:
    """A restart as the restart table shows it: its start, the windows' constants (step 1), the
    one trajectory's (step 2); the loss is the trajectory's mean squared misfit (in spreads)."""
    history = History.for_constants(names)
    history.append(0, math.nan, math.nan, 0.0, init)
    if screen is not None:
        history.append(1, screen.misfit ** 2, screen.misfit ** 2, 0.0, screen.values)
    if full is None:
        final = dict(screen.values) if screen is not None else dict(init)
        return RunRecord(index=index, seed=seed, init=dict(init), final=final, loss=math.inf,
                         steps=len(history) - 1, status="failed", error=why or "its window fit failed",
                         wall_s=wall, history=history, stop_reason="non-finite")
    history.append(2, full.misfit ** 2, full.misfit ** 2, 0.0, full.values)
    final = {n: full.values[n] for n in names}
    return RunRecord(index=index, seed=seed, init=dict(init), final=final, loss=full.misfit ** 2, steps=2,
                     status="ok", converged=full.converged, wall_s=wall, history=history,
                     stop_reason="converged" if full.converged else "max_steps",
                     gauge=dict(full.gauge or {st: {"scale": 1.0, "offset": 0.0} for st in states}))


def fitted_path(x: np.ndarray, fit: TrajectoryFit) -> np.ndarray:
    """The fitted trajectory in x's units, (T, k): the path plus the fit's residual."""
    return np.asarray(x, dtype=np.float64).reshape(len(x), -1) + fit.residuals
