"""Learnable constants: bounds by reparametrisation (never clamping) and learning-rate scales.

Each constant is stored as an unconstrained raw parameter u and read through a map chosen by its
bounds, so every value the optimiser can reach is inside the bounds and the gradient never dies:

| bounds          | value            | lr_scale                          |
| --------------- | ---------------- | --------------------------------- |
| none            | u                | 10**floor(log10 abs(init)) (1 if init = 0): the paper's rule |
| min only        | min + exp(u)     | 1 (a step of lr changes value - min by a factor e**lr: scale-free) |
| max only        | max - exp(u)     | 1                                 |
| min and max     | min + (max - min) sigmoid(u) | 1                     |

So with Adam and a base lr, an unbounded constant moves by about lr * 10**floor(log10|init|)
per step (the paper's rule, exactly: Adam is invariant to a fixed rescaling of the parameter
when the lr is rescaled with it), and a positive constant moves by a relative lr per step
whatever its magnitude. The paper's failure at init 10 (lr 10) was a base lr of 1: with these
scales a base lr near 1e-2 moves any constant by at most ~1-10 % of its magnitude per step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from fitode.eqparse import ParamSpec

from .errors import ParameterError


@dataclass(frozen=True)
class Reparam:
    """The map from a raw parameter to a constant's value."""

    name: str
    lo: float | None = None
    hi: float | None = None

    @property
    def kind(self) -> str:
        if self.lo is not None and self.hi is not None:
            return "sigmoid"
        if self.lo is not None:
            return "log-lower"
        if self.hi is not None:
            return "log-upper"
        return "identity"

    def value(self, u: torch.Tensor) -> torch.Tensor:
        kind = self.kind
        if kind == "identity":
            return u
        if kind == "log-lower":
            return self.lo + torch.exp(u)
        if kind == "log-upper":
            return self.hi - torch.exp(u)
        return self.lo + (self.hi - self.lo) * torch.sigmoid(u)

    def inside(self, v: float) -> bool:
        return (self.lo is None or v > self.lo) and (self.hi is None or v < self.hi)

    def clip(self, v: float) -> float:
        """The nearest value strictly inside the bounds (a small margin from a finite bound)."""
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None:
            margin = 1e-6 * (hi - lo)
            return min(max(v, lo + margin), hi - margin)
        if lo is not None and v <= lo:
            return lo + 1e-6 * max(1.0, abs(lo))
        if hi is not None and v >= hi:
            return hi - 1e-6 * max(1.0, abs(hi))
        return v

    def raw(self, v: float) -> float:
        if not math.isfinite(v):
            raise ParameterError(f"{self.name}: value {v} is not finite")
        if not self.inside(v):
            raise ParameterError(f"{self.name} = {v:g} is outside its bounds {self.describe_bounds()}")
        kind = self.kind
        if kind == "identity":
            return v
        if kind == "log-lower":
            return math.log(v - self.lo)
        if kind == "log-upper":
            return math.log(self.hi - v)
        p = (v - self.lo) / (self.hi - self.lo)
        return math.log(p) - math.log1p(-p)

    def lr_scale(self, v: float) -> float:
        if self.kind != "identity":
            return 1.0
        return 1.0 if v == 0 else 10.0 ** math.floor(math.log10(abs(v)))

    def describe_bounds(self) -> str:
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        return f"({lo}, {hi})"


def reparam_for(name: str, spec: ParamSpec | None) -> tuple[Reparam, float]:
    """The parametrisation of a constant and its initial value (spec.init, else 1.0 or a value inside)."""
    spec = spec or ParamSpec()
    lo = None if spec.min is None else float(spec.min)
    hi = None if spec.max is None else float(spec.max)
    if lo is not None and hi is not None and not lo < hi:
        raise ParameterError(f"{name}: min {lo:g} must be below max {hi:g}")
    rep = Reparam(name, lo, hi)
    if spec.init is not None:
        init = float(spec.init)
        if not rep.inside(init):
            raise ParameterError(f"{name}: initial value {init:g} must lie strictly inside its bounds "
                                 f"{rep.describe_bounds()} (a bounded constant is reparametrised and never "
                                 f"reaches its bound)")
        return rep, init
    return rep, default_init(rep)


def default_init(rep: Reparam) -> float:
    if rep.inside(1.0):
        return 1.0
    if rep.lo is not None and rep.hi is not None:
        return 0.5 * (rep.lo + rep.hi)
    if rep.lo is not None:
        return rep.lo + max(1.0, abs(rep.lo))
    return rep.hi - max(1.0, abs(rep.hi))
