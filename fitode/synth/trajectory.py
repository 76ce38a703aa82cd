"""True trajectories: closed forms where the equation has one, else the project's RK4."""
from __future__ import annotations

import numpy as np

from fitode.errors import FitodeError


def damped_oscillator(t: np.ndarray, g0: float, g1: float, z0: float, v0: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Exact z(t) and z'(t) of z'' + g1 z' + g0 z = 0 with z(0) = z0, z'(0) = v0.

    Under-, critically and over-damped cases are all handled (and g0 < 0, exponential
    growth, for completeness)."""
    t = np.asarray(t, dtype=np.float64)
    zeta = g1 / 2.0
    w2 = g0 - zeta * zeta
    decay = np.exp(-zeta * t)
    a, b0 = z0, v0 + zeta * z0
    if w2 > 1e-12:
        w = np.sqrt(w2)
        c, s = np.cos(w * t), np.sin(w * t)
        b = b0 / w
        core, dcore = a * c + b * s, -a * w * s + b * w * c
    elif w2 < -1e-12:
        k = np.sqrt(-w2)
        c, s = np.cosh(k * t), np.sinh(k * t)
        b = b0 / k
        core, dcore = a * c + b * s, a * k * s + b * k * c
    else:
        core, dcore = a + b0 * t, np.full_like(t, b0)
    z = decay * core
    return z, -zeta * z + decay * dcore


def simulate_system(system, constants: dict[str, float], y0: dict[str, float], n_frames: int,
                    dt: float, substeps: int = 20) -> tuple[np.ndarray, tuple[str, ...], np.ndarray,
                                                             tuple[str, ...]]:
    """Integrate an OdeSystem with the project's RK4 at `substeps` steps per frame (float64).

    y0 names a value for every state and each derivative below its order: {"x": 1, "x'": 0}.
    Missing derivatives default to 0; a missing value is an error.
    Returns (latent (T, dim), state names, full first-order state (T, n), its slot names)."""
    from fitode.codegen import StateLayout, simulate

    layout = StateLayout.from_system(system)
    labels = tuple(s.label for s in layout.slots)
    unknown = set(y0) - set(labels)
    if unknown:
        raise FitodeError(f"initial state names {', '.join(sorted(unknown))} are not in the state "
                          f"({', '.join(labels)})")
    missing_values = [s for s in system.states if s not in y0]
    if missing_values:
        raise FitodeError(f"give an initial value for {', '.join(missing_values)} (--y0 NAME=VALUE)")
    missing_consts = [c for c in system.learnable if c not in constants]
    if missing_consts:
        raise FitodeError(f"give a value for the constant(s) {', '.join(missing_consts)} "
                          f"(--const NAME=VALUE)")
    extra = [c for c in constants if c not in layout.constants]
    if extra:
        raise FitodeError(f"{', '.join(extra)} is not a constant of the equation "
                          f"(its constants: {', '.join(layout.constants) or 'none'})")
    init = {s: [float(y0.get(s + "'" * k, 0.0)) for k in range(system.orders[s])] for s in system.states}
    full = simulate(system, {k: float(v) for k, v in constants.items()}, init, int(n_frames), float(dt),
                    integrator="rk4", substeps=int(substeps), full=True, numpy=True)
    if not np.all(np.isfinite(full)):
        raise FitodeError("the simulated trajectory is not finite (it blows up): choose other "
                          "constants, initial state, dt or number of frames")
    return full[:, list(layout.value_slots)], tuple(layout.states), full, labels
