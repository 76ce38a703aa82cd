"""The gauge: how the equation's state x relates to the encoder's latent z, per state variable.

The KL prior holds z at N(mean, std^2), which fixes z only up to a scale and an offset. The
equation should see the physical state x = s*z + b. Where the equation is unchanged by
rescaling (shifting) a state, or the change is absorbed by a learnable constant, s (b) would be
redundant and stays fixed at 1 (0); where nothing absorbs it, s (b) is learned:
- scale: sin(theta) ties the pendulum's angle to radians, so a latent held at unit variance
  would force a swing of about 1.4 rad and change the period; a learned s lets it be 20 degrees.
- offset: I' = -gamma*I decays to 0, which a zero-mean latent cannot do; sqrt(h) needs h > 0.
The symmetries come from the same numerical test as the identifiability report
(fitode.eqparse.identify). One exception: an oscillator whose equation is odd in its state
(x -> -x maps solutions to solutions, as for the pendulum and every linear oscillator) swings
about its equilibrium at 0, and so does the zero-mean latent; a learned offset there would only
trade against the constants (a pendulum swinging about b has the frequency of length L/cos b),
so it stays 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy

from .identify import _SEED, _Model, _symmetries
from .system import OdeSystem, deriv_symbol


@dataclass(frozen=True)
class StateGauge:
    """x = scale * z + offset for one state; *_learned says which of the two is learned."""

    state: str
    scale_learned: bool
    offset_learned: bool
    positive: bool  # the state sits under sqrt, log or a fractional power: start it inside the domain
    reason: str
    # the equation pins the state's zero (a shift changes its solutions: sin(theta), -k*x), whether or
    # not b is learned: an observation that reads the state with an uncertain zero may refine it
    zero_pinned: bool = False

    def describe(self) -> str:
        s = "s learned" if self.scale_learned else "s = 1"
        b = "b learned" if self.offset_learned else "b = 0"
        return f"{self.state} = s*z + b ({s}, {b}): {self.reason}"


def gauge_plan(system: OdeSystem, *, seed: int = _SEED) -> dict[str, StateGauge]:
    """The gauge of every state of `system` (see the module docstring)."""
    model = _Model(system)
    present = [n for n in system.learnable if any(f.has(model.p[n]) for f in model.f)]
    sym = _symmetries(model, present, model.f, np.random.default_rng(seed))
    odd = system.max_order >= 2 and _odd(system)
    plan = {}
    for s in system.states:
        scale = sym is not None and s in sym.pinned
        offset = sym is not None and s in sym.offset_pinned and not odd
        pinned_offset = sym is not None and s in sym.offset_pinned
        why = ["the equation fixes its scale" if scale else "its scale is free",
               "its zero too" if offset else ("it swings about 0 like the latent" if pinned_offset
                                               else "its zero is free")]
        plan[s] = StateGauge(s, scale, offset, _under_domain(system, s), "; ".join(why), pinned_offset)
    return plan


def _odd(system: OdeSystem) -> bool:
    """True when y -> -y (every state and derivative) maps the equations onto themselves."""
    flip = {deriv_symbol(s, k): -deriv_symbol(s, k) for s in system.states for k in range(system.orders[s] + 1)}
    try:
        pairs = [(system.rhs[s].xreplace(flip), system.rhs[s]) for s in system.states]
        # a sum that is not zero at a generic point is not zero: that settles most equations
        # without sympy's simplify, whose first call alone costs half a second
        if any(_nonzero_somewhere(a, b) for a, b in pairs):
            return False
        return all(sympy.simplify(a + b) == 0 for a, b in pairs)
    except (TypeError, ValueError, RecursionError):
        return False


def _nonzero_somewhere(a: sympy.Expr, b: sympy.Expr) -> bool:
    """True when a + b is clearly not zero at a seeded generic point, beyond the rounding of its
    terms (proof that it is not identically zero); False when it is zero there or cannot be
    evaluated (undecided)."""
    if a + b == 0:
        return False
    rng = np.random.default_rng(_SEED)
    symbols = sorted((a + b).free_symbols | a.free_symbols | b.free_symbols, key=str)
    # exact rational coordinates evaluated to 50 digits: an identity's rounding stays far below the test
    point = {s: sympy.Rational(int(rng.integers(300, 1700)), 1000) for s in symbols}
    try:
        va, vb = (complex(e.xreplace(point).evalf(50)) for e in (a, b))
    except (TypeError, ValueError, ArithmeticError):
        return False
    if not (np.isfinite(va) and np.isfinite(vb)):
        return False
    return abs(va + vb) > 1e-12 * (1.0 + abs(va) + abs(vb))


def _under_domain(system: OdeSystem, state: str) -> bool:
    x = deriv_symbol(state, 0)
    for rhs in system.rhs.values():
        for node in sympy.preorder_traversal(rhs):
            if isinstance(node, sympy.Pow) and node.base.has(x) and not (node.exp.is_integer is True):
                return True
            if isinstance(node, (sympy.log, sympy.asin, sympy.acos)) and node.has(x):
                return True
    return False
