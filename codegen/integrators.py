"""Fixed-step integrators: tiny classes that override one `step`, and a name -> class table.

Same shape as torchdiffeq's fixed-grid solvers. A rollout advances `substeps` steps of
h = dt/substeps per frame interval and keeps one state per frame. Every step works on the whole
batch at once (the state is one tensor of shape (batch, n_slots)); the only Python loop is over
time steps. A rollout of NumPy arrays with a NumPy field (codegen.source.compile_numpy) is the
same steps without gradients, at a fraction of the cost; where the field is affine in the state
(StateLayout.affine), rollout_affine takes no step per frame at all: one frame's steps are an
affine map, and the frames its powers.
"""
from __future__ import annotations

from typing import Callable, ClassVar

import numpy as np
import torch

from .errors import ParameterError
from .layout import StateLayout

Field = Callable[[torch.Tensor], torch.Tensor]


def _axpy(y, x, a: float):
    """y + a x, in one torch kernel for tensors."""
    return torch.add(y, x, alpha=a) if isinstance(y, torch.Tensor) else y + a * x


class Integrator:
    """Base class: subclasses set name, order, formula and implement `step`."""

    name: ClassVar[str] = ""
    order: ClassVar[int] = 0
    formula: ClassVar[str] = ""

    def __init__(self, layout: StateLayout):
        self.layout = layout

    def step(self, f: Field, y: torch.Tensor, h: float) -> torch.Tensor:
        raise NotImplementedError

    def rollout(self, f: Field, y0: torch.Tensor, n_frames: int, dt: float, substeps: int = 1) -> torch.Tensor:
        """States at frames 0..n_frames-1 (frame 0 = y0), shape (..., n_frames, n_slots)."""
        h = float(dt) / substeps
        step = self.step
        y = y0
        ys = [y0]
        for _ in range(n_frames - 1):
            for _ in range(substeps):
                y = step(f, y, h)
            ys.append(y)
        return torch.stack(ys, dim=-2) if isinstance(y0, torch.Tensor) else np.stack(ys, axis=-2)

    def rollout_affine(self, f: Field, y0: np.ndarray, n_frames: int, dt: float, substeps: int = 1) -> np.ndarray:
        """rollout() of NumPy states (B, n_slots) for a field affine in the state (StateLayout.affine),
        in a few array operations instead of one Python step per frame: a frame's steps are then an
        affine map y -> M y + c of their own (read off at the origin and the unit states), and the
        frames are its powers, doubled: frames k..2k-1 are frames 0..k-1 mapped by M^k y + c_k. The
        same states as stepping, to rounding."""
        h = float(dt) / substeps
        batch, n = y0.shape
        # the origin and each unit state, for every rollout of the batch: (n + 1, B, n) so that
        # constants of shape (B,) broadcast as they do against one state per rollout
        probes = np.zeros((n + 1, batch, n))
        probes[np.arange(1, n + 1), :, np.arange(n)] = 1.0
        for _ in range(substeps):
            probes = self.step(f, probes, h)
        c = probes[0]  # (B, n)
        m = np.moveaxis(probes[1:] - c, 0, -1)  # (B, n, n): column j is the map of unit state j
        out = np.empty((batch, n_frames, n))
        out[:, 0] = y0
        k = 1
        while k < n_frames:
            take = min(k, n_frames - k)
            out[:, k:k + take] = np.einsum("bij,btj->bti", m, out[:, :take]) + c[:, None, :]
            c = np.einsum("bij,bj->bi", m, c) + c
            m = m @ m
            k *= 2
        return out


class Euler(Integrator):
    name = "euler"
    order = 1
    formula = "y <- y + h f(y)"

    def step(self, f, y, h):
        return _axpy(y, f(y), h)


class SymplecticEuler(Integrator):
    """Semi-implicit Euler: the highest derivative first, then each lower one from the new value.

    For x'' = a(x, x'):  x'_new = x' + h a(x, x');  x_new = x + h x'_new.  With x'_t taken as
    (x_t - x_{t-1})/dt this is exactly the paper's x_{t+1} = 2 x_t - x_{t-1} + dt^2 a(x_t, x'_t).
    First-order variables get the plain Euler step (as the official code's first-order models do).
    In first-order form: y <- y + h g with g = F(y) + h S g, S shifting each slot's derivative one
    slot down its variable's chain; S is nilpotent, so max_order - 1 passes solve it exactly.
    """

    name = "symplectic"
    order = 1
    formula = ("highest derivative first, then each lower one from the updated value:\n"
               "  x'_new = x' + h f(x, x');  x_new = x + h x'_new\n"
               "  (= the paper's x_{t+1} = 2 x_t - x_{t-1} + dt^2 f(x_t, (x_t - x_{t-1})/dt) when h = dt)")

    def __init__(self, layout):
        super().__init__(layout)
        n = layout.n_slots
        top = set(layout.top_slots)
        self._pairs = [(i, i + 1) for i in range(n) if i not in top]
        self._levels = layout.max_order - 1
        self._shift: dict = {}

    def _shift_matrix(self, ref: torch.Tensor) -> torch.Tensor:
        numpy = not isinstance(ref, torch.Tensor)
        key = ("numpy", ref.dtype) if numpy else (ref.device, ref.dtype)
        m = self._shift.get(key)
        if m is None:
            n = self.layout.n_slots
            m = np.zeros((n, n), dtype=ref.dtype) if numpy else torch.zeros(n, n, dtype=ref.dtype, device=ref.device)
            for i, j in self._pairs:
                m[j, i] = 1.0  # (g @ m)[i] = g[i + 1]
            self._shift[key] = m
        return m

    def step(self, f, y, h):
        fy = f(y)
        g = fy
        if self._levels:
            shift = self._shift_matrix(y)
            for _ in range(self._levels):
                g = _axpy(fy, g @ shift, h)
        return _axpy(y, g, h)


class RK4(Integrator):
    name = "rk4"
    order = 4
    formula = ("k1 = f(y); k2 = f(y + h/2 k1); k3 = f(y + h/2 k2); k4 = f(y + h k3)\n"
               "y <- y + h/6 (k1 + 2 k2 + 2 k3 + k4)")

    def step(self, f, y, h):
        k1 = f(y)
        k2 = f(_axpy(y, k1, h / 2))
        k3 = f(_axpy(y, k2, h / 2))
        k4 = f(_axpy(y, k3, h))
        return _axpy(y, _axpy(k1 + k4, k2 + k3, 2.0), h / 6)


INTEGRATORS: dict[str, type[Integrator]] = {cls.name: cls for cls in (Euler, SymplecticEuler, RK4)}
# The paper's one-step scheme is the semi-implicit Euler step; accept the name users know it by.
ALIASES = {"paper": "symplectic", "semi-implicit": "symplectic", "semi_implicit": "symplectic",
           "explicit-euler": "euler"}


def get_integrator(name: str) -> type[Integrator]:
    key = ALIASES.get(name, name)
    try:
        return INTEGRATORS[key]
    except KeyError:
        raise ParameterError(f"unknown integrator {name!r}; choose one of {', '.join(INTEGRATORS)}") from None
