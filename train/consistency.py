"""Does the equation hold over the whole clip? One trajectory against the measured latent.

A measured latent (a centroid, a radius: observe.py's geometric models) is what the camera saw,
whatever the equation says, so an equation that does not describe the motion does not show as a
bent latent: the windows' fit settles on constants that average over the clip, every restart
agrees, and the number looks trusted. The real slow-motion ball drop is the case in point: in
its last fifth the ball falls visibly behind the parabola of its first frames (a light ball in
air; a camera that looks at the wall at an angle), and the whole clip gives g = 8.0 m/s^2
(-18%) with three restarts agreeing.

Short windows cannot see it: over 20 frames the misfit hides under the noise of the velocity
each window starts from, and a miss measured against the noise depends on how the noise of
neighbouring frames hangs together (motion blur, the codec). The constants say it plainly: the
clip is cut in two and each half is fitted as one trajectory of the equation (fit_trajectory:
its starting state and constants both free, from the fit's values), with a standard error.
Where a constant differs between the halves by more than SIGMAS standard errors and more than
HALVES_APART of its value, one set of constants does not hold over the clip, and that constant's
verdict says so (another whose halves agree keeps its own).
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from .trajectory import TrajectoryFit, fit_trajectory, long_options
from .findings import Finding

HALF_TOL = 0.05
# The halves may differ by less: a constant that drifts over the clip can leave the whole clip's
# value further from the truth than the drift itself, beyond the 5% a trusted number promises. A
# linear pendulum fitted to a 50-degree swing: L 3.7% apart on the halves (12 standard errors), the
# whole clip 5.1% off with a 1.6% interval; a sine pendulum fitted to the real bob: 0.31% apart
HALVES_APART = 0.02
SIGMAS = 3.0


def whole_clip_check(system, params: Mapping, state: np.ndarray, dt: float, start: Mapping[str, float],
                     config) -> tuple[Finding | None, dict[str, list[float]]]:
    """The finding (None where the halves agree, or a half could not be fitted) and the numbers
    behind it: each constant fitted as one trajectory on the first and on the second half of
    state (T, d), with its standard error."""
    x = np.asarray(state, dtype=np.float64)
    half = x.shape[0] // 2
    if half < 8 or not np.all(np.isfinite(x)):
        return None, {}
    halves = [fit_trajectory(system, params, part, dt, start, integrator=config.integrator, substeps=config.substeps,
                             **long_options(len(part))) for part in (x[:half], x[half:])]
    if any(h is None for h in halves):
        return None, {}
    numbers = {n: [halves[0].values[n], halves[0].errors[n], halves[1].values[n], halves[1].errors[n]]
               for n in system.learnable}
    apart, names = [], []
    for n, (a, se_a, b, se_b) in numbers.items():
        gap = abs(a - b)
        if gap > HALVES_APART * max(abs(float(start[n])), 1e-12) and gap > SIGMAS * math.hypot(se_a, se_b):
            apart.append(f"{n} {a:.4g} +- {se_a:.2g} on the first half and {b:.4g} +- {se_b:.2g} on the second")
            names.append(n)
    if not apart:
        return None, numbers
    # for the constants whose halves disagree: a released swing's damping moved 11% between its halves
    # (a slow reading error, which damping feels most) while its length held to 0.01%
    return Finding("ambiguous", "one set of constants does not hold over the whole clip: fitted as one trajectory, "
                   + "; ".join(apart) + " (in the fit's own units): drag, a camera at an angle to the motion or a "
                   "missing term changes the motion; fit only the part where the equation holds (--start/--end) "
                   "or extend the equation", tuple(names)), numbers


def one_trajectory_check(system, params: Mapping, state: np.ndarray, dt: float, values: Mapping[str, float],
                         config, fitted: TrajectoryFit | None = None,
                         ) -> tuple[list[Finding], dict[str, list[float]]]:
    """Do the windows' constants agree with one trajectory of the equation over the whole clip?
    Short windows see little of what acts slowly: a pendulum's light damping takes off a few
    percent of the swing per window, and the windows' damping can land anywhere near it (the real
    bob clip: zeta 0.0166 from the windows, 0.0059 from one trajectory over its 31 s, 0.0056
    from a colour tracker's damped-sine fit). The whole state (T, d) is fitted as one trajectory,
    starting from the windows' constants; each constant farther from it than SIGMAS standard
    errors and HALF_TOL of its value gets an ambiguous finding of its own, which names the
    trajectory's value. fitted: fit_trajectory's result for the same state and start, where the
    caller has it. Returns the findings and each constant's [trajectory value, its error]."""
    x = np.asarray(state, dtype=np.float64)
    if x.shape[0] < 16 or not np.all(np.isfinite(x)):
        return [], {}
    if fitted is None:
        fitted = fit_trajectory(system, params, x, dt, values, integrator=config.integrator, substeps=config.substeps,
                                **long_options(len(x)))
    if fitted is None:
        return [], {}
    found, numbers = [], {}
    for n in system.learnable:
        whole, se = fitted.values[n], fitted.errors[n]
        numbers[n] = [whole, se]
        gap = abs(float(values[n]) - whole)
        if gap > HALF_TOL * max(abs(whole), 1e-12) and gap > SIGMAS * se:
            found.append(Finding("ambiguous", f"the windows give {n} = {float(values[n]):.4g} but one trajectory of the "
                                 f"equation over the whole clip gives {whole:.4g} +- {se:.2g} (in the fit's own units): "
                                 "the windows see too little of what acts slowly (light damping over a few periods); "
                                 "the whole-clip value is the better one", (n,)))
    return found, numbers
