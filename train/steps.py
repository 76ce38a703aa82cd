"""How many integrator steps per frame a measured path needs: as many as make the constants stop moving.

One RK4 step per frame is exact enough for a clip that samples its motion finely, but not where the
frames are coarse: a step loses amplitude and phase by a share of (omega dt)^6 and (omega dt)^5, which
a fit reads as damping and frequency. On the paper's motion video (omega dt = 0.4, 16 frames a
period, a lightly damped swing) one step a frame put g1 0.25% low and g0 0.04% high, 20 times the
residuals' share of its interval; two steps a frame leave 1/32 of that. Which clip needs how many
depends on the equation, its constants and how lightly a swing is damped, so it is measured, not
ruled: the path is fitted again with twice the steps, from the same start, and the steps are doubled
while a constant still moves by more than STEP_SHIFT of itself or STEP_ERRORS of its standard error
(Richardson's test of a step: RK4's error at n steps is 16/15 of the change from n to 2n).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .direct import full_fit
from .trajectory import TrajectoryFit, long_options

STEP_SHIFT = 1e-4  # a constant that moves less than this share of itself when the steps are halved has settled
STEP_ERRORS = 0.1  # ... or less than this many of its standard errors (a constant near zero)
MAX_SUBSTEPS = 32


@dataclass
class Steps:
    """The steps per frame a path needs, and the constants' relative change at each doubling tried."""

    substeps: int
    shifts: list[dict[str, float]] = field(default_factory=list)  # one per doubling tried, relative change per constant
    settled: bool = True  # False: still moving at MAX_SUBSTEPS, or a refit failed

    def to_dict(self) -> dict:
        return {"substeps": self.substeps, "shifts": [dict(s) for s in self.shifts], "settled": self.settled}

    def reason(self, integrator: str) -> str:
        """One line: the steps taken, and what halving the step moved."""
        per = f"{integrator}, {self.substeps} step{'s' if self.substeps != 1 else ''} per frame"
        if not self.shifts:
            return per
        first = self.shifts[0]
        name = max(first, key=lambda n: abs(first[n]))
        moved = f"; one step per frame put {name} {100 * -first[name]:+.3g}% off" if self.substeps > 1 else ""
        if not self.settled:
            last = self.shifts[-1]
            worst = max(last, key=lambda n: abs(last[n]))
            return f"{per}, the most tried: halving the step still moves {worst} by {100 * last[worst]:+.3g}%{moved}"
        return (f"{per}: halving the step again moves no constant by more than {100 * STEP_SHIFT:g}% or "
                f"{STEP_ERRORS:g} standard error{moved}")


def settle_substeps(system, params: Mapping, x: np.ndarray, dt: float, fit: TrajectoryFit, *, gauge: Mapping | None,
                    integrator: str = "rk4", substeps: int = 1, limit: int = MAX_SUBSTEPS) -> Steps:
    """The steps per frame at which one trajectory of the equation through the measured path x (T, k),
    fitted from `fit` (the direct fit's best), has constants that no longer move when the steps are
    halved (see the module docstring). Both fits of a pair start from `fit`, so what the optimiser
    leaves behind cancels; a refit that fails keeps the steps reached (settled False)."""
    options = {"gauge": gauge, "integrator": integrator, **long_options(len(x))}
    steps = Steps(int(substeps))
    here = full_fit(system, params, x, dt, fit, substeps=steps.substeps, **options)
    while here is not None:
        if steps.substeps * 2 > limit:
            steps.settled = False
            break
        finer = full_fit(system, params, x, dt, fit, substeps=steps.substeps * 2, **options)
        if finer is None:
            steps.settled = False
            break
        shift, moved = {}, False
        for name in system.learnable:
            a, b = float(here.values[name]), float(finer.values[name])
            se = float((here.errors or {}).get(name, 0.0) or 0.0)
            shift[name] = (b - a) / abs(a) if a else math.inf
            moved |= not (abs(b - a) <= max(STEP_SHIFT * abs(a), STEP_ERRORS * se if math.isfinite(se) else 0.0))
        steps.shifts.append(shift)
        if not moved:
            break
        steps.substeps *= 2
        here = finer
    return steps
