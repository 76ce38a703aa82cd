"""The units of each constant, built from the units its states are measured in and seconds.

A state read as a*x moves each constant by a power of a (identify.scale_exponents: free fall's g
by a, h' = -k*sqrt(h)'s k by a**0.5); time read in units c times larger moves it by a power of c
(time_exponents: g by c**2, k by c). So a constant's unit is the product of its states' units to
their powers, times seconds to minus its time power: g in px/s^2, k in px^0.5/s.
"""
from __future__ import annotations

from fractions import Fraction
from typing import Mapping

import numpy as np
import sympy

from .identify import _SEED, _diff, _Model, _stack
from .system import OdeSystem


def time_exponents(system: OdeSystem, *, seed: int = _SEED) -> dict[str, float | None]:
    """The power e of the time unit's factor c by which each learnable constant moves when time
    is read in units c times larger (x^(k) -> c^k x^(k)): infinitesimally, for each equation
    x^(n) = f, n*f - sum_k k*y_k*df/dy_k = sum_c e_c*c*df/dc at every sampled point. None where no
    single power holds (a fixed constant with its own time unit, g in the pendulum's g/L, makes L's
    power that of g*s^2: it is reported, but means seconds only where nothing is fixed)."""
    model = _Model(system)
    rng = np.random.default_rng(seed)
    names = list(system.learnable)
    present = [n for n in names if any(f.has(model.p[n]) for f in model.f)]
    out: dict[str, float | None] = {n: 0.0 for n in names}
    if not present:
        return out
    columns = [[model.p[n] * _diff(f, model.p[n]) for f in model.f] for n in present]
    own = []
    for s, f in zip(model.states, model.f):
        order = system.orders[s]
        own.append(order * f - sum((k * y * _diff(f, y) for s2 in model.states
                                    for k, y in enumerate(model.y[s2])), sympy.Integer(0)))
    m = _stack(model, columns + [own], rng)
    if m is None:
        return {n: None if n in present else 0.0 for n in names}
    e, *_ = np.linalg.lstsq(m[:, :-1], m[:, -1], rcond=None)
    if np.max(np.abs(m[:, :-1] @ e - m[:, -1]), initial=0.0) > 1e-6 * (1 + np.max(np.abs(m[:, -1]), initial=0.0)):
        return {n: None if n in present else 0.0 for n in names}
    for n, v in zip(present, e):
        out[n] = float(Fraction(float(v)).limit_denominator(12))
    return out


def constant_units(system: OdeSystem, state_units: Mapping[str, str]) -> dict[str, str | None]:
    """Each learnable constant's unit from its states' units (state -> "px", "m", ...) and
    seconds; None where a power is missing (no pure power of a state's scale moves it), a state
    it depends on has no unit, or a fixed constant (g = 9.80665 m/s^2) brings units of its own."""
    from .identify import scale_exponents

    if system.fixed:
        return {n: None for n in system.learnable}
    powers, times = scale_exponents(system), time_exponents(system)
    out: dict[str, str | None] = {}
    for n in system.learnable:
        p, e = powers.get(n), times.get(n)
        if p is None or e is None or any(v and s not in state_units for s, v in p.items()):
            out[n] = None
            continue
        factors: dict[str, float] = {}
        for s, v in p.items():
            if v:
                factors[state_units[s]] = factors.get(state_units[s], 0.0) + v
        if e:
            factors["s"] = factors.get("s", 0.0) - e
        out[n] = format_unit(factors)
    return out


def format_unit(factors: Mapping[str, float]) -> str:
    """{"px": 1, "s": -2} -> "px/s^2"; {"px": 0.5, "s": -1} -> "px^0.5/s"; {} -> "1"."""
    def part(name: str, power: float) -> str:
        q = Fraction(power).limit_denominator(12)
        if q == 1:
            return name
        text = str(float(q)) if q.denominator in (2, 4, 5) else str(q)
        text = text[:-2] if text.endswith(".0") else text
        return f"{name}^{text}" if q.denominator == 1 or "." in text else f"{name}^({text})"
    up = [part(k, v) for k, v in factors.items() if v > 0]
    down = [part(k, -v) for k, v in factors.items() if v < 0]
    top = "*".join(up) or "1"
    if not down:
        return top
    return f"{top}/{down[0]}" if len(down) == 1 else f"{top}/({'*'.join(down)})"
