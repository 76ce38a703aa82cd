"""The initial state of a window from its first encoded frames (finite differences).

A window's rollout starts at an anchor frame c of its first n_context frames z_0..z_{n-1}. The
state there holds each variable's value, z_c itself, and its derivatives below the equation's
order, estimated by the finite-difference weights of the context frames (Fornberg's weights,
sympy.finite_diff_weights): d^k z/dt^k (t_c) ~ sum_j w_kj z_j / dt^k.

Modes:

- "difference" (default): centred stencil, anchor at the middle frame. n_context is 1 for a
  first-order equation (the value is z_0 itself) and otherwise the smallest odd number >= order
  + 2: 5 frames for z'' = f, z'(t_2) ~ (z_0 - 8 z_1 + 8 z_3 - z_4) / (12 dt), error
  dt^4/30 z^(5). Measured (bench/discretisation.py, damped oscillator at omega*dt = 0.4, RK4 x4,
  least squares on the exact trajectory): the 3-frame (z_2 - z_0)/(2 dt) (error dt^2/6 z''',
  2.7 % of the velocity here) biases g1 by -12.6 % and g0 by -0.07 %; the 5-frame one by -0.4 %
  and -0.00 %. A centred stencil has half the error of the one-sided one of the same order and
  uses the same number of frames, hence centred. `context` overrides (any count >= order).
- "backward": the paper's. n_context = order, anchor = last context frame, one-sided weights:
  z'(t_1) ~ (z_1 - z_0)/dt, error dt/2 z'' (first order). With the semi-implicit Euler step this
  reproduces the paper's update z_{t+1} = 2 z_t - z_{t-1} + dt^2 f(z_t, (z_t - z_{t-1})/dt).
- "learnable": the derivatives are per-window parameters, seeded by a centred stencil of the
  smallest odd number of frames >= order (3 for z'' = f: the stencil only seeds them, and a
  short context leaves more frames to the loss); the value z_c still comes from the encoder.
  On the exact trajectory it removes the initial-state bias entirely (RK4 x4: g0 -0.00 %,
  g1 -0.00 %); with 1 % noise on the latents it stays the least biased (g1 +0.2..0.4 %).
  But in joint training with the encoder (paper videos, 800 steps, RK4) it is no better than
  "difference" on intensity and scale and fails on motion (g1 0.38 instead of 0.08, where
  "difference" gives 0.0787): its values are snapshots of an untrained encoder. Hence not the
  default.

Whatever the mode, frames before the anchor are not predicted: the block copies them from the
input (they are the rollout's inputs); frames after it are the rollout.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy
from sympy.calculus.finite_diff import finite_diff_weights

from .errors import ParameterError

INIT_MODES = ("difference", "backward", "learnable")


@dataclass(frozen=True)
class InitScheme:
    """Finite-difference weights for derivatives 0..max_order-1 at the anchor frame."""

    mode: str
    context: int
    anchor: int
    weights: tuple[tuple[float, ...], ...]
    """weights[k][j]: weight of context frame j in the k-th derivative (divide by dt**k)."""
    exact: tuple[tuple[sympy.Rational, ...], ...]
    error_order: tuple[int, ...]
    """error_order[k]: the k-th derivative's error is O(dt**error_order[k]) (0 for k = 0: exact)."""


def init_scheme(max_order: int, mode: str = "difference", context: int | None = None) -> InitScheme:
    if mode not in INIT_MODES:
        raise ParameterError(f"unknown init {mode!r}; choose one of {', '.join(INIT_MODES)}")
    if context is None:
        if mode == "backward" or max_order == 1:
            context = max_order
        else:
            wanted = max_order + 2 if mode == "difference" else max_order
            context = wanted if wanted % 2 else wanted + 1
    if context < max_order:
        raise ParameterError(f"{context} context frame(s) cannot give the {max_order - 1} derivative(s) "
                             f"an order-{max_order} equation needs; use at least {max_order}")
    anchor = context - 1 if mode == "backward" else (context - 1) // 2
    offsets = [j - anchor for j in range(context)]
    table = finite_diff_weights(max_order - 1, offsets, 0)
    exact = tuple(tuple(sympy.Rational(w) for w in table[k][-1]) for k in range(max_order))
    errors = []
    for k, w in enumerate(exact):
        p = context
        while k > 0 and sum(wj * sympy.Integer(o) ** p for wj, o in zip(w, offsets)) == 0:
            p += 1
        errors.append(p - k if k > 0 else 0)
    weights = tuple(tuple(float(x) for x in w) for w in exact)
    return InitScheme(mode, context, anchor, weights, exact, tuple(errors))


def describe_init(layout, mode: str, context: int | None = None) -> str:
    """Readable formulas of the initial state, e.g. "x' = (-z[0] + z[2])/(2*dt)  error O(dt^2)"."""
    scheme = init_scheme(layout.max_order, mode, context)
    z = sympy.IndexedBase("z")
    dt = sympy.Symbol("dt")
    lines = [f"Initial state ({mode!r}): each latent z from {scheme.context} context frame(s) "
             f"z[0..{scheme.context - 1}]; the rollout starts at frame {scheme.anchor}:"]
    width = len("z" + "'" * (layout.max_order - 1))
    for k in range(layout.max_order):
        expr = sum(w * z[j] for j, w in enumerate(scheme.exact[k])) / dt ** k
        order = scheme.error_order[k]
        err = "exact" if k == 0 else ("error O(dt)" if order == 1 else f"error O(dt^{order})")
        extra = ", then learned per window" if mode == "learnable" and k else ""
        lines.append(f"  {'z' + chr(39) * k:<{width}} = {sympy.sstr(sympy.together(expr))}   ({err}{extra})")
    return "\n".join(lines)
