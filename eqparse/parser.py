"""Equation text -> checked `OdeSystem`.

The grammar lives in grammar.lark; `_ToSympy` turns its tree into sympy expressions and records
where every name occurs, so that each refusal can point at a column.

Names:
- a name written with primes (x', x'') or as dx/dt, d2x/dt2 is a state variable, everywhere in
  the text (a plain `x` elsewhere is its value);
- `pi` and `e` are the exact sympy constants (sympy.pi, sympy.E); they are never states and
  cannot be fixed or freed;
- names in KNOWN_CONSTANTS (`g` = 9.80665 m/s^2) are fixed at that value unless freed;
- every other name is a learnable constant.
Learnable and fixed constants are listed in order of first appearance in the text; states in
the order of their equations.

Implicit equations are solved for their highest derivative without sympy.solve (see
`_solve_for`). Refusals are EquationError: `column` is 1-based within `text`, which is the line
the error is on (the message starts with "line N: " when the input has several lines).
Limits: MAX_LENGTH characters, MAX_DEPTH levels of nesting.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from importlib import resources

import sympy
from lark import Lark, Token, Transformer, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken, VisitError

from .errors import EquationError
from .system import OdeSystem, deriv_symbol
from .typos import likely_typo, nearest

MAX_LENGTH = 2000
"""Longest equation text accepted (characters)."""

MAX_DEPTH = 60
"""Deepest nesting of calls, powers and parentheses accepted (keeps sympy and Python's stack safe)."""

KNOWN_CONSTANTS: dict[str, float] = {"g": 9.80665}
"""Physical constants fixed at these values unless the caller frees them (SI units)."""

NUMBER_ARGUMENT_MAX = 1e6
"""Largest number a function may take as its whole argument (sympy evaluates such a call at once)."""

MATH_CONSTANTS: dict[str, sympy.Expr] = {"pi": sympy.pi, "e": sympy.E}

FUNCTIONS = {
    "sin": sympy.sin, "cos": sympy.cos, "tan": sympy.tan,
    "asin": sympy.asin, "acos": sympy.acos, "atan": sympy.atan,
    "sinh": sympy.sinh, "cosh": sympy.cosh, "tanh": sympy.tanh,
    "exp": sympy.exp, "log": sympy.log, "sqrt": sympy.sqrt,
    "abs": sympy.Abs, "sign": sympy.sign,
}

_SOLVE_MAX_OPS = 120  # sympy.solve can take very long on large non-polynomial expressions

_DERIV_RE = re.compile(r"d(\^?\d+)?([A-Za-z_][A-Za-z_0-9]*)\s*/\s*dt(\^?\d+)?")

_TERMINAL_WORDS = {
    "NUMBER": "a number", "NAME": "a name", "PRIMED": "a derivative", "DERIV": "a derivative",
    "LPAR": "'('", "RPAR": "')'", "ADDOP": "'+' or '-'", "MULOP": "'*' or '/'", "POW": "'^'",
    "EQUAL": "'='", "_SEP": "';' or a new line", "$END": "the end of the text",
}


@dataclass
class _Occurrence:
    name: str
    order: int  # 0 for a plain name
    line: int
    column: int
    lhs: bool = False


@dataclass
class _Equation:
    lhs: sympy.Expr
    rhs: sympy.Expr
    line: int
    column: int  # where the equation starts
    occurrences: list[_Occurrence] = field(default_factory=list)
    explicit: _Occurrence | None = None  # the LHS when it is exactly one derivative
    calls: list[_Call] = field(default_factory=list)


@dataclass
class _Call:
    function: str
    names: set[str]  # the names in the argument, states by their plain name
    has_derivative: bool  # the argument holds x', x'', ... (a plain state is among names)


class _Located(Exception):
    """An error raised inside the transformer, before the text's lines are known to it."""

    def __init__(self, message: str, line: int, column: int):
        super().__init__(message)
        self.message, self.line, self.column = message, line, column


def _grammar() -> Lark:
    global _LARK
    if _LARK is None:
        text = resources.files(__package__).joinpath("grammar.lark").read_text(encoding="utf-8")
        _LARK = Lark(text, parser="lalr", maybe_placeholders=False)
    return _LARK


_LARK: Lark | None = None


def _check_name(tok: Token, name: str, as_state: bool) -> None:
    if name == "t":
        raise _Located("'t' (time) is not allowed: equations must be autonomous", tok.line, tok.column)
    if name in FUNCTIONS:
        raise _Located(f"'{name}' is a function name; call it as {name}(...) or rename the variable",
                       tok.line, tok.column)
    if as_state and name in MATH_CONSTANTS:
        raise _Located(f"'{name}' is the constant {name}; a state variable needs another name",
                       tok.line, tok.column)


def _number(text: str) -> sympy.Expr:
    if re.fullmatch(r"\d+", text):
        return sympy.Integer(text)
    return sympy.Float(text)


def _power(base: sympy.Expr, exp: sympy.Expr) -> sympy.Expr:
    # Exact integer powers of literals can be astronomically large (9^9^9); go through floats then.
    if base.is_Number and exp.is_Number:
        if not (exp.is_Integer and abs(int(exp)) <= 64) or (base.is_Rational and abs(base.p) > 10**12):
            try:
                return sympy.Float(float(base) ** float(exp))
            except (OverflowError, ZeroDivisionError, TypeError, ValueError):
                return sympy.Pow(sympy.Float(base), sympy.Float(exp))
    return sympy.Pow(base, exp)


class _ToSympy(Transformer):
    def __init__(self) -> None:
        super().__init__()
        self.occ: list[_Occurrence] = []
        self.calls: list[_Call] = []

    def number(self, children):
        return _number(str(children[0]))

    def name(self, children):
        tok = children[0]
        name = str(tok)
        _check_name(tok, name, as_state=False)
        if name in MATH_CONSTANTS:
            return MATH_CONSTANTS[name]
        self.occ.append(_Occurrence(name, 0, tok.line, tok.column))
        return sympy.Symbol(name)

    def primed(self, children):
        tok = children[0]
        text = str(tok)
        name = text.split("'")[0].rstrip(" \t")
        order = text.count("'")
        _check_name(tok, name, as_state=True)
        self.occ.append(_Occurrence(name, order, tok.line, tok.column))
        return deriv_symbol(name, order)

    def dfrac(self, children):
        tok = children[0]
        m = _DERIV_RE.fullmatch(str(tok))
        assert m is not None  # the grammar's regex accepted it
        top = int((m.group(1) or "1").lstrip("^"))
        bottom = int((m.group(3) or "1").lstrip("^"))
        name = m.group(2)
        if top != bottom:
            raise _Located(f"'{tok}': the order on top ({top}) and below ({bottom}) differ",
                           tok.line, tok.column)
        if top < 1:
            raise _Located(f"'{tok}': a derivative has order 1 or more", tok.line, tok.column)
        _check_name(tok, name, as_state=True)
        self.occ.append(_Occurrence(name, top, tok.line, tok.column))
        return deriv_symbol(name, top)

    def call(self, children):
        tok, arg = children
        fn = FUNCTIONS.get(str(tok))
        if fn is None:
            if str(tok) == "t":
                _check_name(tok, "t", as_state=False)
            known = ", ".join(FUNCTIONS)
            raise _Located(f"unknown function '{tok}' (known: {known})", tok.line, tok.column)
        if arg.is_number and abs(complex(arg)) > NUMBER_ARGUMENT_MAX:
            # sympy evaluates a function of a number at once, and exp(1e300) runs mpmath for hours
            raise _Located(f"{tok}(...): a function of a number beyond {NUMBER_ARGUMENT_MAX:g} is no constant "
                           "a fit can use; write its value", tok.line, tok.column)
        syms = getattr(arg, "free_symbols", set())
        self.calls.append(_Call(str(tok), {s.name.rstrip("'") for s in syms}, any("'" in s.name for s in syms)))
        return fn(arg)

    def sum(self, children):
        terms = [children[0]]
        for op, value in zip(children[1::2], children[2::2]):
            terms.append(value if op == "+" else -value)
        return sympy.Add(*terms)

    def product(self, children):
        factors = [children[0]]
        for op, value in zip(children[1::2], children[2::2]):
            factors.append(value if op == "*" else sympy.Pow(value, -1))
        return sympy.Mul(*factors)

    def unary(self, children):
        value = children[-1]
        negative = sum(1 for c in children[:-1] if c == "-") % 2 == 1
        return -value if negative else value

    def power(self, children):
        base, _, exp = children
        return _power(base, exp)

    def equation(self, children):
        lhs, eq_tok, rhs = children
        occ, self.occ = self.occ, []
        calls, self.calls = self.calls, []
        for o in occ:
            o.lhs = (o.line, o.column) < (eq_tok.line, eq_tok.column)
        occ.sort(key=lambda o: (o.line, o.column))
        left = [o for o in occ if o.lhs]
        explicit = None
        if len(left) == 1 and left[0].order >= 1 and lhs == deriv_symbol(left[0].name, left[0].order):
            explicit = left[0]
        return _Equation(lhs, rhs, 0, 0, occ, explicit, calls)

    def start(self, children):
        return list(children)


def _depth(tree: Tree) -> int:
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, d = stack.pop()
        deepest = max(deepest, d)
        stack.extend((c, d + 1) for c in node.children if isinstance(c, Tree))
    return deepest


def _first_token(tree: Tree) -> Token | None:
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, Token):
            return node
        stack.extend(reversed(node.children))
    return None


class _Builder:
    """Collects the context for error messages: the lines of the text."""

    def __init__(self, text: str):
        self.text = text
        self.lines = text.split("\n")

    def error(self, message: str, line: int | None = None, column: int | None = None) -> EquationError:
        if line is None or column is None:
            return EquationError(message, None, self.text)
        src = self.lines[line - 1] if 0 < line <= len(self.lines) else self.text
        if len(self.lines) > 1:
            message = f"line {line}: {message}"
        return EquationError(message, column, src)

    def syntax_error(self, exc: UnexpectedInput) -> EquationError:
        line = getattr(exc, "line", None)
        column = getattr(exc, "column", None)
        if isinstance(exc, UnexpectedCharacters):
            char = self.text[exc.pos_in_stream] if exc.pos_in_stream < len(self.text) else "?"
            hint = ""
            if char == "'":
                hint = "; a prime belongs right after a variable name, as in x'"
            elif char.isalpha():
                hint = "; names use the letters a-z and A-Z, digits and _"
            elif char in ",[]{}":
                hint = "; functions take one argument in round brackets"
            return self.error(f"unexpected character {char!r}{hint}", line, column)
        if isinstance(exc, UnexpectedToken):
            tok = exc.token
            if tok.type == "$END":
                line, column = len(self.lines), len(self.lines[-1]) + 1
                what = "end of the text"
            elif tok.type == "_SEP":
                what = "end of the equation" if tok == ";" else "end of the line"
                if tok != ";":
                    column = len(self.lines[line - 1]) + 1
            else:
                what = repr(str(tok))
            before = self.lines[line - 1][: column - 1].rstrip() if line and column else ""
            if tok.type in ("NAME", "PRIMED", "DERIV", "NUMBER", "LPAR") and before and (
                    before[-1].isalnum() or before[-1] in ")_'."):
                return self.error(f"unexpected {what}: multiplication needs an explicit '*'", line, column)
            return self.error(f"unexpected {what}; expected {_describe_expected(exc.expected)}", line, column)
        if isinstance(exc, UnexpectedEOF):
            return self.error("unexpected end of the text", len(self.lines), len(self.lines[-1]) + 1)
        return self.error(f"syntax error: {exc}", line, column)


def _describe_expected(expected: Iterable[str]) -> str:
    names = set(expected)
    if names & {"NUMBER", "NAME", "LPAR"}:
        return "a number, a name or '('"
    if names == {"RPAR"}:
        return "')'"
    words = []
    if names & {"ADDOP", "MULOP", "POW"}:
        words.append("an operator")
    words += [_TERMINAL_WORDS[n] for n in ("RPAR", "EQUAL") if n in names]
    if names & {"_SEP", "$END"}:
        words.append("the end of the equation")
    return " or ".join(words) if words else "something else"


def _derivs(expr: sympy.Expr, states: Mapping[str, int] | Iterable[str]) -> dict[sympy.Symbol, tuple[str, int]]:
    """The state symbols in expr: symbol -> (state, order); order 0 is the state's value."""
    states = set(states)
    found = {}
    for sym in expr.free_symbols:
        name = sym.name.rstrip("'")
        if name in states:
            found[sym] = (name, len(sym.name) - len(name))
    return found


def parse(text: str, *, fix: Mapping[str, float] | None = None, free: Iterable[str] = (),
          declared: Iterable[str] = ()) -> OdeSystem:
    """Parse equation text into a checked OdeSystem.

    fix: constants held at a value (a known one like g=9.81, or one that would be learnable).
    free: known constants (g) made learnable; a learnable name listed here is declared as such.
    declared: names the caller declares constants (an equation file's [parameters]).
    A constant whose name is a likely typo of a state's (`teta` beside theta, eqparse.typos) is an
    EquationError unless fixed, freed or declared; a constant inside sin/cos/tan where the
    equation has states gets a hint in OdeSystem.hints.
    Raises EquationError (with a 1-based column where one applies) for every refusal.
    """
    if not isinstance(text, str):
        raise EquationError("the equation must be text")
    b = _Builder(text)
    if len(text) > MAX_LENGTH:
        raise b.error(f"the equation text is too long ({len(text)} characters; the limit is {MAX_LENGTH})")
    if not re.sub(r"#[^\n]*|[\s;]", "", text):
        raise b.error("the equation text is empty")
    try:
        tree = _grammar().parse(text)
    except UnexpectedInput as exc:
        raise b.syntax_error(exc) from None
    if _depth(tree) > MAX_DEPTH:
        raise b.error(f"the expression is nested too deeply (more than {MAX_DEPTH} levels)")

    starts = []
    for eq_tree in tree.children:
        tok = _first_token(eq_tree)
        starts.append((tok.line, tok.column) if tok is not None else (1, 1))
    try:
        equations: list[_Equation] = _ToSympy().transform(tree)
    except VisitError as exc:
        orig = exc.orig_exc
        if isinstance(orig, _Located):
            raise b.error(orig.message, orig.line, orig.column) from None
        if isinstance(orig, RecursionError):
            raise b.error("the expression is nested too deeply") from None
        raise
    for eq, (line, column) in zip(equations, starts):
        eq.line, eq.column = line, column

    free = [free] if isinstance(free, str) else list(free)
    system = _build(b, equations, dict(fix or {}), free)
    deliberate = set(fix or {}) | set(free) | ({declared} if isinstance(declared, str) else set(declared))
    system.hints = _name_hints(b, equations, system, deliberate)
    return system


# functions whose argument is an angle: where an equation with states means a state
_ANGLE_FUNCTIONS = ("sin", "cos", "tan")


def _name_hints(b: _Builder, equations: list[_Equation], system: OdeSystem, deliberate: set[str]) -> tuple[str, ...]:
    """Refuse a learnable name that is a likely typo of a state; hint at a constant where a state is expected."""
    states = system.states
    for eq in equations:
        for o in eq.occurrences:
            if o.name not in system.learnable or o.name in deliberate:
                continue
            near = [s for s in states if likely_typo(o.name, s)]
            if near:
                s = nearest(o.name, near)
                raise b.error(f"'{o.name}' is not a state: did you mean '{s}'? (as written, {o.name} would be "
                              f"learned as a constant; if that is meant, say so with --free {o.name})",
                              o.line, o.column)
    hints: list[str] = []
    hinted: set[str] = set()
    for eq in equations:
        for c in eq.calls:
            if c.function not in _ANGLE_FUNCTIONS or c.has_derivative or c.names & set(states):
                continue
            for name in sorted(c.names & set(system.learnable) - deliberate - hinted):
                s = nearest(name, states)
                hints.append(f"'{name}' inside {c.function}(...) is a constant to learn, not a state; "
                             f"if you meant the state {s}, write {c.function}({s})")
                hinted.add(name)
    return tuple(hints)


def _build(b: _Builder, equations: list[_Equation], fix: dict[str, float], free: list[str]) -> OdeSystem:
    # A name is a state if it carries a derivative anywhere in the text.
    first_deriv: dict[str, _Occurrence] = {}
    for eq in equations:
        for o in eq.occurrences:
            if o.order >= 1 and o.name not in first_deriv:
                first_deriv[o.name] = o
    state_names = set(first_deriv)

    states: list[str] = []
    orders: dict[str, int] = {}
    rhs: dict[str, sympy.Expr] = {}
    owner: dict[str, _Equation] = {}
    target_occ: dict[str, _Occurrence] = {}

    for eq in equations:
        name, order, expr, occ = _solve(b, eq, state_names)
        if name in owner:
            raise b.error(f"two equations for {name}: one state variable needs exactly one equation",
                          occ.line, occ.column)
        owner[name] = eq
        target_occ[name] = occ
        states.append(name)
        orders[name] = order
        rhs[name] = expr

    for name in state_names:
        if name not in owner:
            o = first_deriv[name]
            raise b.error(f"{name}{chr(39) * o.order} appears but {name} has no equation of its own "
                          f"(add one like {name}' = ...)", o.line, o.column)

    for name in states:
        eq = owner[name]
        for sym, (s, k) in _derivs(rhs[name], orders).items():
            if k >= orders[s] and not (s == name and k < orders[name]):
                o = next((o for o in eq.occurrences if o.name == s and o.order == k), None)
                line, col = (o.line, o.column) if o else (eq.line, eq.column)
                raise b.error(f"{sym.name} on the right-hand side of {name}'s equation: {s}'s equation "
                              f"is for {s}{chr(39) * orders[s]}, so only lower derivatives may appear",
                              line, col)
        bad = rhs[name]
        if bad.has(sympy.zoo, sympy.oo, -sympy.oo, sympy.nan):
            raise b.error(f"the right-hand side of {name}{chr(39) * orders[name]} is not finite "
                          "(a division by zero?)", eq.line, eq.column)
        if bad.has(sympy.I):
            raise b.error(f"the right-hand side of {name}{chr(39) * orders[name]} is complex",
                          eq.line, eq.column)

    # Constants in order of first appearance.
    constants: list[str] = []
    for eq in equations:
        for o in eq.occurrences:
            if o.name not in state_names and o.name not in constants:
                constants.append(o.name)

    def not_a_constant(name: str, what: str) -> EquationError:
        if name in MATH_CONSTANTS:
            return b.error(f"cannot {what} '{name}': it is the mathematical constant {name}")
        if name in state_names:
            return b.error(f"cannot {what} '{name}': it is a state variable, not a constant")
        listed = ", ".join(constants) if constants else "none"
        return b.error(f"cannot {what} '{name}': the equation has no constant named {name} "
                       f"(its constants: {listed})")

    fixed_values: dict[str, float] = {}
    for name, value in fix.items():
        if name not in constants:
            raise not_a_constant(name, "fix")
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise b.error(f"cannot fix '{name}' to {value!r}: not a number") from None
        if not math.isfinite(value):
            raise b.error(f"cannot fix '{name}' to {value}: the value must be finite")
        fixed_values[name] = value
    freed = set()
    for name in free:
        if name not in constants:
            raise not_a_constant(name, "free")
        if name in fixed_values:
            raise b.error(f"'{name}' is both fixed and freed; choose one")
        freed.add(name)

    fixed: dict[str, float] = {}
    learnable: list[str] = []
    for name in constants:
        if name in fixed_values:
            fixed[name] = fixed_values[name]
        elif name in KNOWN_CONSTANTS and name not in freed:
            fixed[name] = KNOWN_CONSTANTS[name]
        else:
            learnable.append(name)

    return OdeSystem(states=tuple(states), orders=orders, rhs=rhs, fixed=fixed,
                     learnable=tuple(learnable), text=b.text)


def _solve(b: _Builder, eq: _Equation, state_names: set[str]) -> tuple[str, int, sympy.Expr, _Occurrence]:
    """The state an equation is for, its order, the right-hand side of that highest derivative."""
    derivs = [o for o in eq.occurrences if o.order >= 1]
    if not derivs:
        plain_state = next((o for o in eq.occurrences if o.name in state_names), None)
        if plain_state is not None:
            raise b.error(f"this equation has no derivative: an equation must give a derivative of a "
                          f"state (like {plain_state.name}' = ...)", eq.line, eq.column)
        raise b.error("this equation names no state variable: write the derivative with primes "
                      "(x' or x'') or as dx/dt", eq.line, eq.column)

    if eq.explicit is not None:
        target = eq.explicit
        for o in eq.occurrences:
            if not o.lhs and o.name == target.name and o.order >= target.order:
                raise b.error(f"{o.name}{chr(39) * o.order} on the right-hand side: its order must be "
                              f"below the left-hand side's ({target.name}{chr(39) * target.order})",
                              o.line, o.column)
        return target.name, target.order, eq.rhs, target

    # Implicit form: solve for the highest derivative left after sympy's own simplification.
    expr = eq.lhs - eq.rhs
    present = _derivs(expr, state_names)
    present = {s: v for s, v in present.items() if v[1] >= 1}
    if not present:
        raise b.error("the derivatives cancel out of this equation", eq.line, eq.column)
    top = max(k for _, k in present.values())
    tops = sorted({n for n, k in present.values() if k == top})
    occ_of = {(o.name, o.order): o for o in reversed(eq.occurrences)}
    if len(tops) > 1:
        o = occ_of.get((tops[1], top))
        line, col = (o.line, o.column) if o else (eq.line, eq.column)
        shown = " and ".join(f"{n}{chr(39) * top}" for n in tops)
        raise b.error(f"cannot tell which derivative this equation is for: {shown} have the same order; "
                      f"write it as {tops[0]}{chr(39) * top} = ...", line, col)
    name = tops[0]
    target_sym = deriv_symbol(name, top)
    occ = occ_of.get((name, top)) or _Occurrence(name, top, eq.line, eq.column)
    solution = _solve_for(b, expr, target_sym, eq)
    return name, top, solution, occ


# Inverses of one-to-one functions, for isolating a derivative nested inside them.
_INVERSES = {
    sympy.exp: sympy.log, sympy.log: sympy.exp, sympy.sinh: sympy.asinh, sympy.asinh: sympy.sinh,
    sympy.tanh: sympy.atanh, sympy.atanh: sympy.tanh, sympy.asin: sympy.sin, sympy.acos: sympy.cos,
    sympy.atan: sympy.tan,
}


def _solve_for(b: _Builder, expr: sympy.Expr, target: sympy.Symbol, eq: _Equation) -> sympy.Expr:
    """Solve expr = 0 for target, refusing anything without exactly one real solution.

    sympy.solve is deliberately not used: on transcendental input it can run for minutes. Three
    cases are solved directly: linear in the target; the target occurring once, under one-to-one
    functions that are inverted step by step; a fraction whose numerator is linear in the target.
    """
    shown = target.name

    def refuse(why: str) -> EquationError:
        return b.error(f"cannot solve this equation for {shown}: {why}; write it as {shown} = ...",
                       eq.line, eq.column)

    if expr.is_polynomial(target):
        degree = sympy.degree(expr, target)
        if degree != 1:
            raise b.error(f"cannot solve uniquely for {shown}: it appears to the power {degree}; "
                          f"write the equation as {shown} = ...", eq.line, eq.column)
        return _linear(expr, target, refuse)
    if expr.count(target) == 1:
        return _isolate(expr, target, refuse)
    num, den = sympy.fraction(sympy.together(expr))
    if num.is_polynomial(target) and sympy.degree(num, target) == 1:
        solution = _linear(num, target, refuse)
        if den.has(target) and den.subs(target, solution) == 0:
            raise refuse("the only candidate makes a denominator zero")
        return solution
    raise refuse("it appears in a form that has no unique closed-form solution")


def _linear(expr: sympy.Expr, target: sympy.Symbol, refuse) -> sympy.Expr:
    coeff = sympy.diff(expr, target)
    if coeff == 0:
        raise refuse("its coefficient is zero")
    # Distribute the division over the sum (-c*x'/m - k*x/m) without expanding powers.
    return sympy.expand(-expr.subs(target, 0) / coeff, deep=False, power_base=False, power_exp=False,
                        multinomial=False, log=False)


def _isolate(expr: sympy.Expr, target: sympy.Symbol, refuse) -> sympy.Expr:
    lhs, rhs = expr, sympy.Integer(0)
    while lhs != target:
        if lhs.is_Add or lhs.is_Mul:
            inner = next(a for a in lhs.args if a.has(target))
            rest = lhs.func(*[a for a in lhs.args if not a.has(target)])
            rhs = rhs - rest if lhs.is_Add else rhs / rest
            lhs = inner
        elif lhs.is_Pow:
            base, exponent = lhs.args
            if base.has(target):
                if exponent.is_Rational and abs(exponent.p) == 1:
                    rhs, lhs = rhs ** (1 / exponent), base
                else:
                    raise refuse(f"it is raised to the power {exponent}, which has no unique inverse")
            else:
                rhs, lhs = sympy.log(rhs) / sympy.log(base), exponent
        elif isinstance(lhs, sympy.Function) and len(lhs.args) == 1:
            inverse = _INVERSES.get(lhs.func)
            if inverse is None:
                raise refuse(f"{lhs.func.__name__.lower()} is not one-to-one")
            rhs, lhs = inverse(rhs), lhs.args[0]
        else:
            raise refuse("it appears in a form that cannot be inverted")
    return rhs
