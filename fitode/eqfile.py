"""Equation files: `equations/<name>.toml`, and turning --eq / --eq-file / --system into an OdeSystem.

Format (every key but `name` and `equation` optional):

    name = "pendulum"
    description = "..."
    equation = "theta'' = -g/L*sin(theta) - zeta*theta'"
    alternatives = ["theta'' = -g/L*theta - zeta*theta'"]   # candidates compared with `equation`
    stride = 2                      # suggested frame stride
    observe = "brightness"          # what the camera measures (fitode.train.observe.catalog), or one per
                                    # state: observe = { x = "position", y = "size" }
    [constants]                     # fixed at these values
    g = 9.80665
    [parameters]                    # learnable constants
    L = { init = 1.0, min = 0.0, unit = "m" }
    zeta = { init = 0.1 }
    [prior]                         # prior on the latent, N(mean, std^2)
    mean = 0.0
    std = 1.0

[constants] are passed to the parser as fixed values. `alternatives` lists other equations for the same
states: `fitode VIDEO --eq-file FILE` fits `equation` and each of them on the same measured path and
prefers the one that predicts held-out stretches best (fitode.compare, docs/comparison.md); every
other use of the file reads `equation` alone. The file's tables apply to each candidate where it
has the name. A known constant (g) listed under
[parameters] is made learnable (the free-fall file does this). Every name in either table must
be a constant of the equation.
"""
from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from fitode.eqparse import KNOWN_CONSTANTS, EquationError, OdeSystem, ParamSpec, parse
from fitode.errors import FitodeError
from fitode.names import parse_names

_PACKAGE = "fitode.equations"
_TOP_KEYS = {"name", "description", "equation", "alternatives", "constants", "parameters", "prior", "stride",
             "observe"}
_PARAM_KEYS = {"init", "min", "max", "unit"}
_PRIOR_KEYS = {"mean", "std"}


@dataclass
class EquationSpec:
    """One equation file, checked."""

    name: str
    equation: str
    constants: dict[str, float] = field(default_factory=dict)
    parameters: dict[str, ParamSpec] = field(default_factory=dict)
    prior_mean: float = 0.0
    prior_std: float = 1.0
    stride: int | None = None
    observe: str | dict[str, str] | None = None  # a model's name, or one per state
    description: str = ""
    path: str | None = None
    alternatives: tuple[str, ...] = ()  # further candidate equations, compared with `equation`

    @property
    def candidates(self) -> list[str]:
        """The candidate equations as written: `equation`, then the alternatives."""
        return [self.equation, *self.alternatives]

    def candidate(self, index: int) -> "EquationSpec":
        """The file as if candidate `index` were its only equation: its tables kept where the
        candidate has the name (a damping rate one candidate lacks is no error of the file)."""
        from dataclasses import replace
        text = self.candidates[index]
        names = constant_names(text, [*self.constants, *self.parameters])
        return replace(self, equation=text, alternatives=(),
                       constants={k: v for k, v in self.constants.items() if k in names},
                       parameters={k: v for k, v in self.parameters.items() if k in names})

    def parse(self, const: Mapping[str, float] | None = None, free: Iterable[str] = ()) -> OdeSystem:
        """The file's system, with the caller's fixed and freed constants over the file's."""
        const = dict(const or {})
        free = list(free)
        fix = {k: v for k, v in self.constants.items() if k not in free}
        fix.update(const)
        freed = [n for n in self.parameters if n in KNOWN_CONSTANTS and n not in const and n not in free]
        return parse(self.equation, fix=fix, free=freed + free, declared=tuple(self.parameters))


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FitodeError(f"{where} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise FitodeError(f"{where} must be finite, got {value}")
    return value


def _unknown(keys: Iterable[str], allowed: set[str], where: str) -> None:
    extra = sorted(set(keys) - allowed)
    if extra:
        raise FitodeError(f"{where}: unknown key{'s' if len(extra) > 1 else ''} {', '.join(extra)} "
                          f"(allowed: {', '.join(sorted(allowed))})")


def spec_from_dict(data: Mapping, where: str, path: str | None = None) -> EquationSpec:
    """Check a parsed TOML table and build the EquationSpec; errors name `where` (the file)."""
    _unknown(data, _TOP_KEYS, where)
    for key in ("name", "equation"):
        if not isinstance(data.get(key), str) or not data[key].strip():
            raise FitodeError(f"{where}: '{key}' is missing (a text value is required)")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise FitodeError(f"{where}: 'description' must be text")

    constants_table = data.get("constants", {})
    if not isinstance(constants_table, dict):
        raise FitodeError(f"{where}: [constants] must be a table of NAME = VALUE")
    constants = {k: _number(v, f"{where}: constant {k}") for k, v in constants_table.items()}

    params_table = data.get("parameters", {})
    if not isinstance(params_table, dict):
        raise FitodeError(f"{where}: [parameters] must be a table of NAME = {{ init, min, max, unit }}")
    parameters = {}
    for name, entry in params_table.items():
        here = f"{where}: parameter {name}"
        if not isinstance(entry, dict):
            raise FitodeError(f"{here} must be a table like {{ init = 1.0, min = 0.0, unit = \"m\" }}")
        _unknown(entry, _PARAM_KEYS, here)
        values = {k: _number(entry[k], f"{here}: {k}") for k in ("init", "min", "max") if k in entry}
        unit = entry.get("unit")
        if unit is not None and not isinstance(unit, str):
            raise FitodeError(f"{here}: unit must be text")
        lo, hi, init = values.get("min"), values.get("max"), values.get("init")
        if lo is not None and hi is not None and lo >= hi:
            raise FitodeError(f"{here}: min ({lo:g}) must be below max ({hi:g})")
        if init is not None and ((lo is not None and init < lo) or (hi is not None and init > hi)):
            raise FitodeError(f"{here}: init ({init:g}) is outside [min, max]")
        parameters[name] = ParamSpec(init=init, min=lo, max=hi, unit=unit)
    both = sorted(set(constants) & set(parameters))
    if both:
        raise FitodeError(f"{where}: {', '.join(both)} is both a fixed constant and a parameter")

    prior = data.get("prior", {})
    if not isinstance(prior, dict):
        raise FitodeError(f"{where}: [prior] must be a table with mean and std")
    _unknown(prior, _PRIOR_KEYS, f"{where}: [prior]")
    mean = _number(prior.get("mean", 0.0), f"{where}: prior mean")
    std = _number(prior.get("std", 1.0), f"{where}: prior std")
    if std <= 0:
        raise FitodeError(f"{where}: prior std must be positive, got {std:g}")

    stride = data.get("stride")
    if stride is not None and (isinstance(stride, bool) or not isinstance(stride, int) or stride < 1):
        raise FitodeError(f"{where}: stride must be a positive whole number, got {stride!r}")

    from fitode.train.observe.catalog import parse_observe
    try:
        observe = parse_observe(data.get("observe"))
    except FitodeError as exc:
        raise FitodeError(f"{where}: {exc}") from None

    alternatives = data.get("alternatives", [])
    if not isinstance(alternatives, list) or not all(isinstance(a, str) and a.strip() for a in alternatives):
        raise FitodeError(f"{where}: 'alternatives' must be a list of equations as text")
    spec = EquationSpec(name=data["name"].strip(), equation=data["equation"], constants=constants,
                        parameters=parameters, prior_mean=mean, prior_std=std, stride=stride, observe=observe,
                        description=" ".join(description.split()), path=path, alternatives=tuple(alternatives))
    try:
        system = spec.parse()
        for i in range(1, len(spec.candidates)):
            spec.candidate(i).parse()
    except EquationError as exc:
        raise FitodeError(f"{where}: {exc}") from None
    unknown = [n for n in parameters if n not in system.learnable]
    if unknown:
        raise FitodeError(f"{where}: [parameters] names {', '.join(unknown)}, which "
                          f"{'is' if len(unknown) == 1 else 'are'} not a learnable constant of the equation "
                          f"(learnable: {', '.join(system.learnable) or 'none'})")
    from fitode.train.observe.catalog import check_states
    try:
        check_states(observe, system.states)
    except FitodeError as exc:
        raise FitodeError(f"{where}: {exc}") from None
    return spec


def load_equation_file(path: str | Path) -> EquationSpec:
    """Read and check one equation file. FitodeError on a missing file, bad TOML or bad content."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise FitodeError(f"equation file not found: {path}") from None
    except OSError as exc:
        raise FitodeError(f"cannot read equation file {path}: {exc.strerror or exc}") from None
    return _from_bytes(raw, str(path), str(path))


def _from_bytes(raw: bytes, where: str, path: str | None) -> EquationSpec:
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise FitodeError(f"{where}: not a UTF-8 text file") from None
    except tomllib.TOMLDecodeError as exc:
        raise FitodeError(f"{where}: not valid TOML ({exc})") from None
    return spec_from_dict(data, where, path)


def _shipped() -> dict[str, resources.abc.Traversable]:
    root = resources.files(_PACKAGE)
    return {p.name[: -len(".toml")]: p for p in root.iterdir() if p.name.endswith(".toml")}


def list_systems() -> list[str]:
    """Names of the shipped equation files, sorted."""
    return sorted(_shipped())


def load_system(name: str) -> EquationSpec:
    """A shipped equation file by name; the error lists the available names."""
    files = _shipped()
    if name not in files:
        raise FitodeError(f"no shipped system named {name!r} (available: {', '.join(sorted(files))})")
    return _from_bytes(files[name].read_bytes(), f"system {name}", str(files[name]))


def resolve(eq: str | None = None, eq_file: str | None = None, system: str | None = None,
            const: Mapping[str, float] | None = None, free: Iterable[str] = (),
            candidate: int | None = None) -> tuple[OdeSystem, EquationSpec | None]:
    """Exactly one of equation text, equation file or shipped system name -> (OdeSystem, spec).

    A file's [constants] are fixed, its known constants listed under [parameters] are freed, then
    the caller's const (fix) and free (make learnable) override both. spec is None for text.
    candidate: which of several candidate equations (candidate_texts: a list of texts as eq, or
    a file's alternatives); the caller's const and free then apply where the candidate has the
    name. None: the one equation (a file's `equation`).
    """
    if isinstance(eq, (list, tuple)):
        texts = list(eq)
        eq = texts[candidate or 0] if texts else None
    given = [(flag, v) for flag, v in (("--eq", eq), ("--eq-file", eq_file), ("--system", system)) if v is not None]
    if len(given) != 1:
        shown = ", ".join(flag for flag, _ in given) if given else "none"
        raise FitodeError(f"give exactly one of --eq, --eq-file or --system (got {shown})")
    const = dict(const or {})
    free = parse_names(list(free))
    if eq is not None:
        if candidate is not None:
            const, free = _present(eq, const, free, ())
        return parse(eq, fix=const, free=free), None
    spec = load_equation_file(eq_file) if eq_file is not None else load_system(system)
    if candidate is not None:
        if not 0 <= candidate < len(spec.candidates):
            raise FitodeError(f"the equation file has {len(spec.candidates)} candidate equations, not {candidate + 1}")
        spec = spec.candidate(candidate)
        const, free = _present(spec.equation, const, free, [*spec.constants, *spec.parameters])
    return spec.parse(const, free), spec


def _present(text: str, const: dict[str, float], free: list[str], declared) -> tuple[dict[str, float], list[str]]:
    """const and free kept to the names the candidate equation has (the others are another candidate's)."""
    names = constant_names(text, [*declared, *const, *free])
    return {k: v for k, v in const.items() if k in names}, [n for n in free if n in names]


def constant_names(text: str, declared: Iterable[str] = ()) -> set[str]:
    """The names of the constants (learnable and known) of equation text; EquationError for bad text."""
    system = parse(text, declared=tuple(declared))
    return set(system.learnable) | set(system.fixed)


def candidate_texts(eq: str | list[str] | tuple[str, ...] | None = None, eq_file: str | None = None,
                    system: str | None = None) -> list[str]:
    """The candidate equations as the user wrote them: each --eq given (repeatable), or an equation
    file's `equation` and `alternatives`; one text where there is a single equation."""
    if isinstance(eq, (list, tuple)):
        if not eq:
            raise FitodeError("give at least one equation")
        return [str(e) for e in eq]
    if eq is not None:
        return [eq]
    if eq_file is not None or system is not None:
        spec = load_equation_file(eq_file) if eq_file is not None else load_system(system)
        return spec.candidates
    return []
