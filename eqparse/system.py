"""The checked ODE system every later layer consumes."""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy
from sympy.printing.precedence import precedence
from sympy.printing.str import StrPrinter


def deriv_symbol(name: str, k: int) -> sympy.Symbol:
    """The sympy symbol standing for the k-th time derivative of state `name`.

    Primes are part of the symbol's name (x, x', x''), so expressions print as the user
    wrote them; codegen maps these symbols onto slices of the state tensor.
    """
    return sympy.Symbol(name + "'" * k)


class _Printer(StrPrinter):
    """sympy's str printer, with the positive terms of a sum first: sin(a) - mu*cos(a)."""

    def _print_Add(self, expr, order=None):
        terms = sorted(expr.args, key=lambda t: (t.could_extract_minus_sign(), sympy.default_sort_key(t)))
        out = ""
        for t in terms:
            neg = t.could_extract_minus_sign()
            body = self.parenthesize(-t if neg else t, precedence(expr))
            out += (" - " if neg else " + ") + body if out else ("-" if neg else "") + body
        return out


def format_expr(expr: sympy.Expr) -> str:
    """Readable text for an expression (sympy's str syntax, positive terms first)."""
    return _Printer().doprint(expr)


@dataclass(frozen=True)
class ParamSpec:
    """What an equation file says about one learnable constant."""

    init: float | None = None
    min: float | None = None
    max: float | None = None
    unit: str | None = None


@dataclass
class OdeSystem:
    """An autonomous ODE system in normal form.

    states: state variable names in a stable order (order of their first equation).
    orders: highest derivative order of each state.
    rhs: for each state, the expression of its highest derivative in terms of
        deriv_symbol(state, k) for k below its order, the learnable constants and the
        fixed constants (as plain Symbols named like the constants).
    fixed: fixed constants and their values (g, pi, e, or ones the caller fixed).
    learnable: learnable constant names in a stable order.
    text: the original equation text.
    hints: the parser's advice that stops nothing, one line each (shown before a fit, kept in its warnings).
    """

    states: tuple[str, ...]
    orders: dict[str, int]
    rhs: dict[str, sympy.Expr]
    fixed: dict[str, float] = field(default_factory=dict)
    learnable: tuple[str, ...] = ()
    text: str = ""
    hints: tuple[str, ...] = ()  # one-line advice from the parser (a constant where a state is expected)

    @property
    def max_order(self) -> int:
        return max(self.orders.values())

    @property
    def dim(self) -> int:
        """Number of latent dimensions: one per state variable."""
        return len(self.states)

    def normal_form(self) -> list[str]:
        """One line per state, e.g. "x'' = -g*sin(x)/L - z*x'"."""
        return [f"{s}{chr(39) * self.orders[s]} = {format_expr(self.rhs[s])}" for s in self.states]
