"""Is the measured path read through a perspective? The bend a camera at an angle puts on a line
of motion, found by the trajectory fitter, and the reading that takes it off again."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .consistency import SIGMAS
from .trajectory import PERSPECTIVE, TrajectoryFit, fit_trajectory, long_options

BEND_MIN = 0.01  # a perspective that bends the path's ends by less changes nothing worth a second training
# ... and one that bends them by more (the near end 3 times as magnified as the far one) is no
# camera's: a bend of 0.75 made one trajectory of a throw's flight and the rest after its landing
# (a stretch grown too far), and the path read through it gave g 0.13 for 19.2
BEND_MAX = 0.5


def perspective_check(system, params: Mapping, state: np.ndarray, dt: float, start: Mapping[str, float],
                      config, straight: TrajectoryFit | None = None) -> dict | None:
    """Is the measured path read through a perspective? A camera that looks at a line of motion
    at an angle sees equal steps along it as unequal ones, nearer larger, which is a
    one-dimensional homography of the position: a fall filmed from below the ceiling looks as if
    it slowed down (the real ball drop: g 16 on the first half of the clip against 11 on the
    second, in latent units). The single trajectory of the equation is fitted to the whole path
    read straight and read through a bend (fit_trajectory with bend=True); the bend is to be
    applied where it is SIGMAS standard errors from zero, bends the ends of the path by at least
    BEND_MIN and at most BEND_MAX, and fits better. A bend cannot make a parabola of another parabola (nor any law
    of itself with other constants), so the bend that fits is the camera's, not a re-reading
    of the dynamics: its one number is decided by the whole clip.

    straight: fit_trajectory's result for the same state and start, where the caller has it.
    None for a latent of more than one dimension or a fit that fails; otherwise the numbers:
    c and its error, the middle m the bend is about (x -> m + (x - m) / (1 + c (x - m))), the
    bend at the path's ends, the misfit read straight and bent, and whether to apply it."""
    x = np.asarray(state, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 1 or x.shape[0] < 16 or not np.all(np.isfinite(x)):
        return None
    options = {"integrator": config.integrator, "substeps": config.substeps, **long_options(len(x))}
    if straight is None:
        straight = fit_trajectory(system, params, x, dt, start, **options)
    bent = fit_trajectory(system, params, x, dt, start, bend=True, **options)
    if straight is None or bent is None:
        return None
    c, se = bent.values[PERSPECTIVE], bent.errors[PERSPECTIVE]
    middle = float(x.mean())
    ends = abs(c) * float(np.abs(x - middle).max())
    misfit = [straight.misfit, bent.misfit]
    apply = abs(c) > SIGMAS * se and BEND_MIN <= ends <= BEND_MAX and misfit[1] < misfit[0]
    return {"c": c, "se": se, "middle": middle, "bend_at_ends": ends, "misfit": misfit, "apply": bool(apply),
            "constants": {n: [straight.values[n], bent.values[n]] for n in system.learnable}}


def unbend(x: np.ndarray, c: float, middle: float) -> np.ndarray | None:
    """x read through the perspective bend about middle; None where a frame lies beyond the
    bend's pole (a held-out frame far outside the range the bend was fitted on)."""
    d = np.asarray(x, dtype=np.float64) - middle
    denominator = 1.0 + c * d
    if np.any(denominator <= 0.05):
        return None
    return middle + d / denominator
