"""What a latent can measure: separability and scale of each learnable constant.

The encoder learns every state only up to the scale and offset that the prior imposes, and the
loss only sees the right-hand sides f(y; p) of the equations. Two questions per learnable
constant p_i, both decided numerically at seeded random points, with exact sympy derivatives:

Separable. J[r, i] = d f_r / d p_i is evaluated at many sampled states y (one generic draw of
the constants, fixed constants at their values) and the rows of all equations and points are
stacked. p_i is separable when e_i lies in the row space of J, i.e. every null vector of J has a
zero i-th component. Otherwise only combinations of constants are measurable: constants linked
through a null vector form a group, and the group's combinations are named by writing each f_r
as sum_j c_j(p) * phi_j(y) (expand, split each term into its constant and state factors); the
coefficients c_j that involve the group are what the video measures (x'' = -k/m*x gives k/m;
the sliding block gives sin(alpha) - mu*cos(alpha)). When a right-hand side does not split that
way the report gives the number of measurable combinations instead of naming them.

Scale. Replace a state x by a*z + b. Infinitesimally (a = 1 + da, b = db) the equation for z
changes by V = sum_k y_k * df/dy_k - [own equation] f (scale; y_k = x, x', ..., whose
derivatives all scale by a) and W = df/dx (offset). The change can be absorbed by new constant
values p + dp exactly when alpha*V + beta*W = J dp, so the symmetries of the equation are the
null space of [V_1..V_S, W_1..W_S, -J] over the sampled points. A constant is "dependent" when
some symmetry moves it (after removing the directions J cannot see): its value is tied to the
latent's units (h' = -k*sqrt(h): k -> k/sqrt(a); free fall h'' = g: g -> g/a). It is "free"
when no symmetry moves it and every state it touches can be rescaled freely (I' = -gamma*I).
A state whose scale no symmetry changes is "pinned", for one of three reasons, told apart by
repeating the test: (1) a known constant sets it (v' = -g - c*v*|v|: with g made learnable the
scale is free again); (2) fixed numbers set it even in the linear part (x'' = 1 - k*x^3); in
both cases the constants are "free", measured in the units those fixed values impose; (3)
nonlinear terms set it (sin(theta), x^2 in Van der Pol). Then the equations are linearised at
the origin (the small-amplitude motion) and the test is repeated there: a constant that no
symmetry of the linear system moves is "free-small-amplitude" (the pendulum's L); one that is
moved, that vanishes in the linear part, or where no linearisation exists is "dependent".

Limits: the linearisation is taken at the origin, not at an equilibrium elsewhere (the
Brusselator's); absurd inputs (x^(10^10)) can overflow the sampled values, and then the rank is
only as good as the finite samples.
"""
from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from fractions import Fraction
from typing import Iterable

import numpy as np
import sympy

from .system import OdeSystem, deriv_symbol, format_expr

SCALES = ("free", "dependent", "free-small-amplitude")

_SEED = 20250101
_TOL = 1e-7
_PREFIX = "enters only through "
_MAX_NAMED = 8  # most measurable combinations named in a report  # relative tolerance on singular values and null-vector components


@dataclass(frozen=True)
class ConstantReport:
    """What the video can tell about one learnable constant."""

    name: str
    separable: bool
    combination: str | None  # the measurable combination when not separable
    scale: str  # one of SCALES
    reason: str


@dataclass(frozen=True)
class IdentifiabilityReport:
    constants: tuple[ConstantReport, ...]
    rank: int  # number of independent measurable combinations of the learnable constants
    notes: tuple[str, ...] = ()

    def __getitem__(self, name: str) -> ConstantReport:
        for c in self.constants:
            if c.name == name:
                return c
        raise KeyError(name)

    def lines(self) -> list[str]:
        if not self.constants:
            return ["no learnable constants: nothing to estimate"]
        width = max(len(c.name) for c in self.constants)
        out = []
        for c in self.constants:
            sep = "separable" if c.separable else (
                f"only as {c.combination}" if c.combination else "not measurable")
            out.append(f"{c.name:<{width}}  {sep:<12}  scale: {c.scale}")
            reason = c.reason
            if c.combination and reason.startswith(_PREFIX + c.combination + "; "):
                reason = reason[len(_PREFIX + c.combination + "; "):]
            out.append(f"{'':<{width}}    {reason}")
        n = len(self.constants)
        if self.rank < n:
            out.append(f"{self.rank} of {n} constants can be told apart from a video")
        out += list(self.notes)
        return out


_ANALYSED: dict = {}


def analyse(system: OdeSystem, *, seed: int = _SEED) -> IdentifiabilityReport:
    """Classify every learnable constant of `system` (see the module docstring for how). The
    report is kept per equation and seed: one run asks for it three times (the header, the fit's
    units, the assessment), at a few hundred milliseconds of sympy each."""
    key = (system.states, tuple(sorted(system.orders.items())), tuple(system.rhs[s] for s in system.states),
           tuple(sorted(system.fixed.items())), system.learnable, seed)
    if key not in _ANALYSED:
        _ANALYSED[key] = _analyse(system, seed)
    return _ANALYSED[key]


def _analyse(system: OdeSystem, seed: int) -> IdentifiabilityReport:
    names = list(system.learnable)
    if not names:
        return IdentifiabilityReport((), 0)
    model = _Model(system)
    rng = np.random.default_rng(seed)

    present = [n for n in names if any(model.f[r].has(model.p[n]) for r in range(model.n_eq))]
    sep = _separability(model, present, rng)
    if sep is None:
        reports = tuple(ConstantReport(n, False, None, "dependent",
                                       "could not be analysed: the right-hand side is not finite at the "
                                       "sampled points") for n in names)
        return IdentifiabilityReport(reports, 0, ("the identifiability analysis failed to evaluate the equation",))
    rank, separable, groups = sep

    full = _symmetries(model, present, model.f, rng)
    order = model.states.index
    # Why a state's scale cannot change: a known constant (g) sets it, fixed numbers set it even in
    # the linear part, or nonlinear terms set it (then only the small-amplitude motion is free).
    by_known: set[str] = set()
    by_numbers: set[str] = set()
    linear: _Symmetry | bool = False
    if full is not None and full.pinned:
        if system.fixed:
            freed_system = OdeSystem(system.states, system.orders, system.rhs, {},
                                     system.learnable + tuple(system.fixed), system.text)
            freed_model = _Model(freed_system)
            freed_present = [n for n in freed_system.learnable if any(f.has(freed_model.p[n]) for f in freed_model.f)]
            freed = _symmetries(freed_model, freed_present, freed_model.f, rng)
            if freed is not None:
                by_known = full.pinned - freed.pinned
        rest = full.pinned - by_known
        if rest:
            linear = _linearised(model, present, rng)
            if linear is not False:
                by_numbers = rest & linear.pinned
    by_nonlinear = (full.pinned - by_known - by_numbers) if full is not None else set()

    decomp = _coefficients(system, model) if not all(separable[n] for n in present) else None
    named: dict[tuple[str, ...], str] = {}
    reports = []
    for name in names:
        if name not in present:
            reports.append(ConstantReport(name, False, None, "free",
                                          "does not appear in the solved equation, so the video cannot tell its value"))
            continue
        touched = model.touched(name)
        if not separable[name]:
            group = groups[name]
            key = tuple(group)
            if key not in named:
                named[key] = _combination(group, decomp, model, rank_of_group=groups_rank(model, group, rng))
            combination = named[key]
            sep_text = f"{_PREFIX}{combination}; "
        else:
            combination, sep_text = None, ""
        if full is None:
            scale, why = "dependent", "the scale analysis could not evaluate the equation"
        elif name in full.dependent:
            scale = "dependent"
            why = (f"its value changes when {_moved(full, name, order)}, so it comes out in the units the "
                   "state is measured in (source pixels, metres with --scale; a free encoder's arbitrary "
                   "units unless calibrated)")
        elif not (touched & full.pinned):
            scale = "free"
            why = f"its value does not change when {_are(sorted(touched, key=order))} rescaled"
        elif not (touched & by_nonlinear):
            pinned = sorted(touched & full.pinned, key=order)
            scale = "free"
            why = (f"{_fixed_terms(system, set(pinned))} the scale of "
                   f"{_join(pinned)}, and no other rescaling changes its value")
        else:
            pinned_list = sorted(touched & by_nonlinear, key=order)
            pinned = _join(pinned_list)
            if linear is False:
                scale = "dependent"
                why = (f"the nonlinear terms fix the scale of {pinned}, and the equations have no "
                       "linearisation at 0 to test the small-amplitude case")
            elif not any(fl.has(model.p[name]) for fl in linear.f):
                scale = "dependent"
                why = f"appears only in nonlinear terms, which tie its value to the scale of {pinned}"
            elif name in linear.dependent:
                scale = "dependent"
                why = (f"the nonlinear terms fix the scale of {pinned}; even in the small-amplitude "
                       f"(linearised) equation its value changes when {_moved(linear, name, order)}")
            else:
                scale = "free-small-amplitude"
                why = (f"the nonlinear terms fix the scale of {pinned} only at large amplitude; in the "
                       f"small-amplitude (linearised) equation its value does not change when "
                       f"{_are(pinned_list)} rescaled")
        reports.append(ConstantReport(name, separable[name], combination, scale, sep_text + why))

    notes = []
    if by_nonlinear:
        notes.append(f"the nonlinear terms fix the scale of {_join(sorted(by_nonlinear, key=order))}: at large "
                     "amplitude the encoder must learn it in the equation's own units")
    if by_known | by_numbers:
        pinned = sorted(by_known | by_numbers, key=order)
        notes.append(f"{_fixed_terms(system, set(pinned))} the scale of "
                     f"{_join(pinned)}: the encoder must learn it in the equation's own units")
    if power_symmetric(system):
        notes.append("a first-order linear equation: any power of the state (minus its rest level) obeys "
                     "the same equation with the rate multiplied by that power, so a nonlinear encoder "
                     "(mlp, cnn) can report any rate; the default encoder (auto) is therefore linear")
    return IdentifiabilityReport(tuple(reports), rank, tuple(notes))


def scale_exponents(system: OdeSystem, *, seed: int = _SEED) -> dict[str, dict[str, float] | None]:
    """The power of each state's scale by which each learnable constant transforms: read every
    state x_s (and its derivatives) as a_s * x_s, and the equations hold again with each constant
    c times prod_s a_s**p_s (free fall d'' = g: g -> a*g, p = 1; h' = -k*sqrt(h): p = 1/2;
    x'' = -w2*x: p = 0). None for a constant that no pure power moves (the pendulum's L under a
    rescaled angle, a constant tied to an offset) or where the equation cannot be evaluated.

    Infinitesimally (a_s = 1 + da) the condition is linear in the powers, sum_c p_c * c * df_r/dc
    = [own equation] f_r - sum_k y_k df_r/dy_k over the sampled points; the least-squares powers
    are rounded to simple fractions and then checked on the finite change (a_s = 0.6 and 1.7),
    where a power that only holds to first order fails."""
    model = _Model(system)
    rng = np.random.default_rng(seed)
    names = list(system.learnable)
    out: dict[str, dict[str, float] | None] = {n: {} for n in names}
    present = [n for n in names if any(f.has(model.p[n]) for f in model.f)]
    for r_s, s in enumerate(model.states):
        columns = [[model.p[n] * _diff(f, model.p[n]) for f in model.f] for n in present]
        own = [(f if r == r_s else sympy.Integer(0)) - sum((y * _diff(f, y) for y in model.y[s]), sympy.Integer(0))
               for r, f in enumerate(model.f)]
        m = _stack(model, columns + [own], rng)
        powers = None
        if m is not None:
            p = np.linalg.lstsq(m[:, :-1], m[:, -1], rcond=None)[0] if present else np.zeros(0)
            powers = [Fraction(float(v)).limit_denominator(12) for v in p]
            if any(abs(float(q) - v) > 1e-6 for q, v in zip(powers, p)) or \
                    not _holds_scaled(model, r_s, dict(zip(present, powers)), rng):
                powers = None
        for i, n in enumerate(names):
            if out[n] is None:
                continue
            if n not in present:
                out[n][s] = 0.0
            elif powers is None:
                out[n] = None
            else:
                out[n][s] = float(powers[present.index(n)])
    return out


def _holds_scaled(model: _Model, r_s: int, powers: dict[str, Fraction], rng) -> bool:
    """Do the equations hold again, at the sampled points, with state r_s read as a * x and each
    constant times a**power, for a = 0.6 and a = 1.7?"""
    s = model.states[r_s]
    for a in (sympy.Rational(3, 5), sympy.Rational(17, 10)):
        sub = {y: a * y for y in model.y[s]}
        sub.update({model.p[n]: model.p[n] * a ** sympy.Rational(q.numerator, q.denominator)
                    for n, q in powers.items()})
        gap = [f.xreplace(sub) - (a if r == r_s else 1) * f for r, f in enumerate(model.f)]
        ref = [f for f in model.f]
        m = _stack(model, [gap, ref], rng)
        if m is None or not np.all(np.abs(m[:, 0]) <= 1e-8 * (1 + np.abs(m[:, 1]))):
            return False
    return True


def power_symmetric(system: OdeSystem) -> bool:
    """x' = a*(x - c) is solved by (x - c)**p with rate p*a: true for one linear first-order state."""
    if len(system.states) != 1 or system.max_order != 1:
        return False
    x = deriv_symbol(system.states[0], 0)
    rhs = system.rhs[system.states[0]]
    return rhs.has(x) and sympy.diff(rhs, x, 2) == 0 and any(c.name in system.learnable for c in rhs.free_symbols)


def sign_odd(system: OdeSystem, states: Iterable[str] | None = None) -> set[str]:
    """The learnable constants that change sign when every state does (or only `states`): the
    equations hold for (-x, -c) whenever they hold for (x, c), as g in d'' = g. Two restarts whose
    latents point opposite ways report such a constant with opposite signs; it is one value."""
    turned = set(system.states if states is None else states)
    flip = {}
    for s, order in system.orders.items():
        if s in turned:
            for k in range(order):
                flip[deriv_symbol(s, k)] = -deriv_symbol(s, k)
    odd = set()
    for name in system.learnable:
        c = sympy.Symbol(name)
        flipped = {**flip, c: -c}
        # a turned state's derivative turns with it; every other state's stays as it was
        if all(sympy.simplify(rhs.xreplace(flipped) + (rhs if s in turned else -rhs)) == 0
               for s, rhs in system.rhs.items()) and any(rhs.has(c) for rhs in system.rhs.values()):
            odd.add(name)
    return odd


def _are(items) -> str:
    items = list(items)
    return _join(items) + (" are" if len(items) > 1 else " is")


def _fixed_terms(system: OdeSystem, states: set[str]) -> str:
    """The fixed constants in these states' equations, as subject and verb of a sentence."""
    used = [n for n in system.fixed if any(system.rhs[s].has(sympy.Symbol(n)) for s in states)]
    if not used:
        return "the equation's fixed numbers set"
    return f"the known constant {used[0]} sets" if len(used) == 1 else f"the known constants {_join(used)} set"


def _join(items) -> str:
    items = list(items)
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


# --- the numeric model -----------------------------------------------------------------------


class _Model:
    """The right-hand sides over real symbols, fixed constants substituted, ready to evaluate."""

    def __init__(self, system: OdeSystem):
        self.system = system
        self.states = list(system.states)
        self.n_eq = len(self.states)
        # Real symbols make d|x|/dx = sign(x) instead of expressions in re() and im().
        self.y: dict[str, list[sympy.Symbol]] = {}
        sub = {}
        for s in self.states:
            syms = []
            for k in range(system.orders[s]):
                real = sympy.Symbol(f"_y_{s}_{k}", real=True)
                sub[deriv_symbol(s, k)] = real
                syms.append(real)
            self.y[s] = syms
        self.p = {n: sympy.Symbol(f"_p_{n}", real=True) for n in system.learnable}
        sub.update({sympy.Symbol(n): self.p[n] for n in system.learnable})
        sub.update({sympy.Symbol(n): sympy.Float(v) for n, v in system.fixed.items()})
        self.sub = sub
        self.f = [system.rhs[s].xreplace(sub) for s in self.states]
        self.all_y = [y for s in self.states for y in self.y[s]]

    def touched(self, name: str) -> set[str]:
        """States whose equation holds the constant, and the states those equations read."""
        p = self.p[name]
        out = set()
        for r, s in enumerate(self.states):
            if self.f[r].has(p):
                out.add(s)
                out |= {t for t in self.states if any(self.f[r].has(y) for y in self.y[t])}
        return out


def _diff(expr: sympy.Expr, sym: sympy.Symbol) -> sympy.Expr:
    d = sympy.diff(expr, sym)
    # sign(x)' is a Dirac delta: zero at every generic point.
    return d.replace(lambda e: isinstance(e, sympy.DiracDelta), lambda e: sympy.Integer(0))


def _evaluate(exprs: list[sympy.Expr], args: list[sympy.Symbol], values: np.ndarray) -> np.ndarray:
    """exprs at each row of values -> array (rows, len(exprs)); non-finite entries become nan."""
    fn = sympy.lambdify(args, exprs, modules="numpy", dummify=True)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            out = fn(*values.T)
        except (ArithmeticError, ValueError, TypeError, NameError, AttributeError):
            return np.full((values.shape[0], len(exprs)), np.nan)
    cols = []
    for col in out:
        a = np.asarray(col)
        if np.iscomplexobj(a):
            a = np.where(np.abs(a.imag) <= 1e-12 * (1 + np.abs(a.real)), a.real, np.nan)
        a = np.broadcast_to(a.astype(float, copy=False), (values.shape[0],))
        cols.append(a)
    res = np.stack(cols, axis=1) if cols else np.zeros((values.shape[0], 0))
    res[~np.isfinite(res)] = np.nan
    return res


_STATE_RANGES = ((0.2, 1.8, 24), (-1.8, 1.8, 24), (2.0, 8.0, 16))
_PARAM_RANGES = ((0.5, 1.5), (0.1, 0.9), (1.5, 4.0))


def _points(model: _Model, rng: np.random.Generator, n_cols: int):
    """Yield (values, args) sample sets: states over several ranges, one draw of the constants.

    At least three rows per column, so that the rank is never limited by the sample size."""
    n_y = len(model.all_y)
    base = sum(n for _, _, n in _STATE_RANGES) * model.n_eq
    more = max(1, -(-3 * n_cols // base))
    ys = np.concatenate([rng.uniform(lo, hi, size=(n * more, n_y)) for lo, hi, n in _STATE_RANGES])
    for lo, hi in _PARAM_RANGES:
        p = rng.uniform(lo, hi, size=len(model.p))
        yield np.hstack([ys, np.broadcast_to(p, (ys.shape[0], len(p)))])


def _stack(model: _Model, columns: list[list[sympy.Expr]], rng: np.random.Generator) -> np.ndarray | None:
    """Evaluate columns[c][r] (one expression per equation r) at the sample points, stacking the
    rows of all equations; None when too few points give finite values."""
    args = model.all_y + list(model.p.values())
    flat = [columns[c][r] for r in range(model.n_eq) for c in range(len(columns))]
    need = max(2 * len(columns), 8)
    for values in _points(model, rng, len(columns)):
        vals = _evaluate(flat, args, values)  # (points, n_eq * n_cols)
        vals = vals.reshape(values.shape[0], model.n_eq, len(columns))
        ok = np.all(np.isfinite(vals), axis=(1, 2))
        if ok.sum() >= need:
            return vals[ok].reshape(-1, len(columns))
    return None


def _normalise(a: np.ndarray) -> np.ndarray:
    """Unit columns (zero columns stay zero); dividing by the largest entry first avoids overflow."""
    peak = np.max(np.abs(a), axis=0) if a.size else np.ones(a.shape[1])
    peak[peak == 0] = 1.0
    a = a / peak
    norms = np.linalg.norm(a, axis=0)
    norms[norms == 0] = 1.0
    return a / norms


def _null_space(a: np.ndarray) -> tuple[int, np.ndarray]:
    """(rank, orthonormal basis of the null space as columns) of a (rows, cols)."""
    if a.size == 0:
        return 0, np.eye(a.shape[1])
    _, s, vt = np.linalg.svd(a, full_matrices=a.shape[0] < a.shape[1])
    if s.size == 0 or s[0] == 0:
        return 0, np.eye(a.shape[1])
    rank = int(np.sum(s > _TOL * s[0]))
    return rank, vt[rank:].T


def _separability(model: _Model, present: list[str], rng):
    separable = {n: False for n in model.p}
    groups: dict[str, list[str]] = {}
    if not present:
        return 0, separable, groups
    cols = [[_diff(f, model.p[n]) for f in model.f] for n in present]
    jac = _stack(model, cols, rng)
    if jac is None:
        return None
    rank, null = _null_space(_normalise(jac))
    parent = {n: n for n in present}

    def root(n):
        while parent[n] != n:
            n = parent[n]
        return n

    proj = null @ null.T
    for i, a in enumerate(present):
        separable[a] = bool(np.all(np.abs(null[i]) < 1e-6))
        for j in range(i + 1, len(present)):
            if abs(proj[i, j]) > 1e-8:
                parent[root(present[j])] = root(a)
    for a in present:
        if not separable[a]:
            groups[a] = [b for b in present if not separable[b] and root(b) == root(a)]
    return rank, separable, groups


def groups_rank(model: _Model, group: list[str], rng) -> int:
    cols = [[_diff(f, model.p[n]) for f in model.f] for n in group]
    jac = _stack(model, cols, rng)
    return 0 if jac is None else _null_space(_normalise(jac))[0]


@dataclass
class _Symmetry:
    f: list[sympy.Expr]
    dependent: dict[str, set[str]]  # constant -> the states whose scale/offset move it
    pinned: set[str]  # states whose scale no symmetry changes
    offset_pinned: set[str]


def _symmetries(model: _Model, present: list[str], f: list[sympy.Expr], rng) -> _Symmetry | None:
    states = model.states
    scale_cols, offset_cols = [], []
    for s in states:
        scale_cols.append([sum((y * _diff(f[r], y) for y in model.y[s]), sympy.Integer(0))
                           - (f[r] if states[r] == s else 0) for r in range(model.n_eq)])
        offset_cols.append([_diff(f[r], model.y[s][0]) for r in range(model.n_eq)])
    j_cols = [[-_diff(fr, model.p[n]) for fr in f] for n in present]
    m = _stack(model, scale_cols + offset_cols + j_cols, rng)
    if m is None:
        return None
    n_s = len(states)
    m = _normalise(m)
    _, null = _null_space(m)
    gen, dp = null[: 2 * n_s], null[2 * n_s:]
    if present:
        _, j_null = _null_space(m[:, 2 * n_s:])
        dp = dp - j_null @ (j_null.T @ dp)  # directions J cannot see move nothing measurable
    dependent: dict[str, set[str]] = {}
    for i, n in enumerate(present):
        moving = np.abs(dp[i]) > 1e-6
        if moving.any():
            movers = set()
            for k in np.nonzero(moving)[0]:
                for j in np.nonzero(np.abs(gen[:, k]) > 1e-6)[0]:
                    movers.add((states[j % n_s], "scale" if j < n_s else "offset"))
            dependent[n] = movers
    pinned = {s for j, s in enumerate(states) if np.all(np.abs(gen[j]) < 1e-6)}
    offset_pinned = {s for j, s in enumerate(states) if np.all(np.abs(gen[n_s + j]) < 1e-6)}
    return _Symmetry(f, dependent, pinned, offset_pinned)


def _moved(sym: _Symmetry, name: str, order) -> str:
    movers = sym.dependent.get(name, set())
    scaled = sorted({s for s, kind in movers if kind == "scale"}, key=order)
    shifted = sorted({s for s, kind in movers if kind == "offset"} - set(scaled), key=order)
    parts = []
    if scaled:
        parts.append(_are(scaled) + " rescaled")
    if shifted:
        parts.append(f"the zero of {_are(shifted)} moved")
    return " or ".join(parts) if parts else "the latent is rescaled"


def _linearised(model: _Model, present: list[str], rng) -> _Symmetry | bool:
    zero = {y: 0 for y in model.all_y}
    f_lin = []
    for fr in model.f:
        try:
            terms = [fr.xreplace(zero)] + [_diff(fr, y).xreplace(zero) * y for y in model.all_y]
        except (ArithmeticError, ValueError, TypeError):
            return False
        lin = sympy.Add(*terms)
        if lin.has(sympy.zoo, sympy.oo, -sympy.oo, sympy.nan):
            return False
        f_lin.append(lin)
    sym = _symmetries(model, [n for n in present if any(fl.has(model.p[n]) for fl in f_lin)], f_lin, rng)
    return False if sym is None else sym


# --- naming the measurable combinations ------------------------------------------------------


def _expansion_size(expr: sympy.Expr) -> int:
    """A bound on the number of terms one power of a sum expands into ((x + a + b)^60 is huge)."""
    worst = 1
    for power in expr.atoms(sympy.Pow):
        base, exponent = power.args
        if base.is_Add and exponent.is_Integer and abs(int(exponent)) > 1:
            n, e = len(base.args), min(abs(int(exponent)), 10**6)
            worst = max(worst, math.comb(n + e - 1, e) if e < 10**4 else 10**9)
    return worst


def _coefficients(system: OdeSystem, model: _Model) -> list[sympy.Expr] | None:
    """The coefficients c_j(p) of f_r = sum_j c_j(p) * phi_j(y) over all equations, or None when
    some right-hand side does not split into constant and state factors."""
    state_syms = [deriv_symbol(s, k) for s in system.states for k in range(system.orders[s])]
    learn = [sympy.Symbol(n) for n in system.learnable]
    coeffs = []
    for s in system.states:
        expr = system.rhs[s]
        if sympy.count_ops(expr) > 400 or _expansion_size(expr) > 500:
            return None
        try:
            expanded = sympy.expand(expr)
        except (ArithmeticError, ValueError, TypeError, RecursionError):
            return None
        by_state: dict[sympy.Expr, sympy.Expr] = {}
        for term in sympy.Add.make_args(expanded):
            const, dep = term.as_independent(*state_syms, as_Add=False)
            if dep.has(*learn):
                return None
            by_state[dep] = by_state.get(dep, sympy.Integer(0)) + const
        coeffs += [c for c in by_state.values() if c.has(*learn)]
    return coeffs


def _clean(expr: sympy.Expr, learn: list[sympy.Symbol]) -> sympy.Expr:
    """Drop numeric and fixed-constant factors and the sign: -9.81*k/m -> k/m."""
    try:
        expr = sympy.factor(expr) if sympy.count_ops(expr) < 60 else expr
    except (ArithmeticError, ValueError, TypeError, sympy.PolynomialError):
        pass
    if expr.is_Mul:
        _, expr = expr.as_independent(*learn, as_Add=False)
    # 1/(C*R) reads better as C*R: the video measures either equally well.
    numer, denom = expr.as_numer_denom()
    if numer.is_Number and denom != 1:
        expr = denom
    return expr


def _distribute_sign(expr: sympy.Expr) -> sympy.Expr:
    """-g*(a - b) -> g*(b - a), so a sign is carried inside a sum rather than in front."""
    if expr.is_Mul:
        coeff, rest = expr.as_coeff_Mul()
        if coeff < 0:
            factors = list(sympy.Mul.make_args(rest))
            for i, f in enumerate(factors):
                if f.is_Add:
                    factors[i] = -f
                    return sympy.Mul(-coeff, *factors, evaluate=False) if coeff != -1 else sympy.Mul(*factors, evaluate=False)
    return expr


def _show(expr: sympy.Expr) -> str:
    """The sign of a measurable combination is arbitrary: print the sign that reads best."""
    candidates = [format_expr(_distribute_sign(e)) for e in (expr, -expr)]
    first = lambda t: len(re.split(r" [-+] ", t.lstrip("-"))[0])  # noqa: E731
    return min(candidates, key=lambda t: (t.startswith("-"), t.count(" - "), len(t), first(t)))


def _combination(group: list[str], coeffs: list[sympy.Expr] | None, model: _Model, rank_of_group: int) -> str:
    names = _join(group)
    learn = [sympy.Symbol(n) for n in model.system.learnable]
    group_syms = [sympy.Symbol(n) for n in group]
    involved = [c for c in coeffs or () if c.has(*group_syms)]
    seen: list[sympy.Expr] = []
    if len(involved) <= _MAX_NAMED:  # beyond that a list of formulas helps nobody
        for c in involved:
            cleaned = _clean(c, learn)
            if not any(cleaned == s or cleaned == 1 / s for s in seen):
                seen.append(cleaned)
    if not seen:
        return f"{rank_of_group} combination{'s' if rank_of_group != 1 else ''} of {names}"
    return ", ".join(_show(s) for s in seen)
