"""First-order reduction: which slot of the state vector holds which derivative of which variable.

A system of any order becomes y' = F(y) with y holding, for each state variable in the system's
order, the variable and its derivatives below its order, contiguously:

    x'' = f(x, x'),  v' = g(x, v)   ->   y = [x, x', v],   F = [x', f, g]

Every slot also gets a Python identifier for the generated source (x' -> x_t, x'' -> x_tt),
since primes are not valid in Python names.
"""
from __future__ import annotations

import keyword
import re
from dataclasses import dataclass
from functools import cached_property

import sympy

from fitode.eqparse import OdeSystem, deriv_symbol

from .errors import CodegenError

# Names the generated module itself uses; user names that collide get a trailing underscore.
_RESERVED = {"torch", "numpy", "math", "state", "out", "vector_field", "subterms", "__builtins__"}


@dataclass(frozen=True)
class Slot:
    """One entry of the first-order state vector: derivative `k` of variable `state`."""

    state: str
    k: int
    symbol: sympy.Symbol
    ident: str

    @property
    def label(self) -> str:
        """How the user writes it: x, x', x''."""
        return self.state + "'" * self.k


class NameAllocator:
    """Python identifiers for user names: sanitised, never a keyword, never twice."""

    def __init__(self) -> None:
        self._used: set[str] = set(_RESERVED)

    def take(self, wanted: str) -> str:
        ident = re.sub(r"\W", "_", wanted)
        if not ident or ident[0].isdigit():
            ident = "_" + ident
        while keyword.iskeyword(ident) or ident in self._used:
            ident += "_"
        self._used.add(ident)
        return ident


@dataclass(frozen=True)
class StateLayout:
    """The first-order form of an OdeSystem (see module docstring)."""

    states: tuple[str, ...]
    orders: tuple[int, ...]
    slots: tuple[Slot, ...]
    derivatives: tuple[sympy.Expr, ...]
    """d/dt of each slot: the next slot's symbol, or the system's rhs for the top slot."""
    constants: tuple[str, ...]
    """Constant names in the generated function's argument order: learnable, then fixed."""
    const_idents: tuple[str, ...]
    n_learnable: int

    @property
    def n_slots(self) -> int:
        return len(self.slots)

    @property
    def dim(self) -> int:
        return len(self.states)

    @property
    def max_order(self) -> int:
        return max(self.orders)

    @property
    def value_slots(self) -> tuple[int, ...]:
        """Slot index of each state's value (k = 0), in state order: what the encoder sees."""
        return tuple(i for i, s in enumerate(self.slots) if s.k == 0)

    @property
    def derivative_slots(self) -> tuple[int, ...]:
        """Slot indices with k >= 1 (the ones an initial state must estimate)."""
        return tuple(i for i, s in enumerate(self.slots) if s.k >= 1)

    @property
    def top_slots(self) -> tuple[int, ...]:
        """Slot index of each state's highest stored derivative (where the rhs goes), state order."""
        order = dict(zip(self.states, self.orders))
        return tuple(i for i, s in enumerate(self.slots) if s.k == order[s.state] - 1)

    @cached_property  # sympy's derivatives, asked once per layout (a compiled field's layout is shared)
    def affine(self) -> bool:
        """Is the field affine in the state (x'' = -a, a spring, a decay): each right-hand side's
        derivative by every slot free of the slots? Then one step of any of the integrators is an
        affine map of the state, which integrators.Integrator.rollout_affine powers up instead of
        stepping frame by frame. A function sympy cannot differentiate cleanly (sign, Abs,
        Piecewise) leaves a slot or a Derivative behind and is not affine."""
        slots = {s.symbol for s in self.slots}
        for expr in self.derivatives:
            for s in slots:
                try:
                    d = sympy.diff(expr, s)
                except Exception:  # noqa: BLE001 - anything sympy cannot differentiate is not affine
                    return False
                if d.free_symbols & slots or d.has(sympy.Derivative, sympy.Subs):
                    return False
        return True

    def index(self, state: str, k: int) -> int:
        for i, s in enumerate(self.slots):
            if s.state == state and s.k == k:
                return i
        raise KeyError(f"{state}{chr(39) * k}")

    @classmethod
    def from_system(cls, system: OdeSystem) -> "StateLayout":
        names = NameAllocator()
        slots: list[Slot] = []
        for state in system.states:
            for k in range(system.orders[state]):
                slots.append(Slot(state, k, deriv_symbol(state, k), names.take(state + "_" + "t" * k if k else state)))
        constants = tuple(system.learnable) + tuple(n for n in system.fixed if n not in system.learnable)
        const_idents = tuple(names.take(n) for n in constants)

        known = {s.symbol for s in slots} | {sympy.Symbol(n) for n in constants}
        derivatives: list[sympy.Expr] = []
        for i, slot in enumerate(slots):
            if slot.k + 1 < system.orders[slot.state]:
                derivatives.append(slots[i + 1].symbol)
                continue
            rhs = sympy.sympify(system.rhs[slot.state])
            unknown = sorted(str(s) for s in rhs.free_symbols - known)
            if unknown:
                raise CodegenError(
                    f"{slot.state}{chr(39) * system.orders[slot.state]} = {sympy.sstr(rhs)}: "
                    f"{', '.join(unknown)} is neither a state slot nor a constant of the system")
            derivatives.append(rhs)
        return cls(tuple(system.states), tuple(system.orders[s] for s in system.states), tuple(slots),
                   tuple(derivatives), constants, const_idents, len(system.learnable))
