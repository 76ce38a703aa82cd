"""`fitode check`: parse an equation and report what a video of it can measure.

    fitode check --eq "x'' = -g/L*sin(x) - z*x'"
    fitode check --system pendulum --const g=9.81
    fitode check --eq-file my_system.toml --free g
    fitode check --list
"""
from __future__ import annotations

import argparse
import textwrap

from fitode.describe import gauge_lines, hint_lines
from fitode.errors import FitodeError
from fitode.options import add_equation_arguments

_WIDTH = 100


def add_arguments(p: argparse.ArgumentParser) -> None:
    # not required: --list stands in for an equation
    _, src = add_equation_arguments(p, title="equation (exactly one, or --list)", required=False)
    src.add_argument("--list", action="store_true", help="list the shipped systems and exit")


def run(args: argparse.Namespace) -> int:
    from fitode.eqfile import list_systems, load_system, resolve
    from fitode.eqparse import analyse
    from fitode.names import parse_assignments, parse_names

    if args.list:
        for line in _list_lines(list_systems(), load_system):
            print(line)
        return 0
    if args.eq is None and args.eq_file is None and args.system is None:
        raise FitodeError("give one of --eq TEXT, --eq-file PATH or --system NAME (or --list)")
    const = parse_assignments(args.const, "--const")
    free = parse_names(args.free, "--free")
    system, spec = resolve(eq=args.eq, eq_file=args.eq_file, system=args.system, const=const, free=free)
    for line in report_lines(system, spec, analyse(system)):
        print(line)
    return 0


def _list_lines(names, load) -> list[str]:
    width = max((len(n) for n in names), default=0)
    out = []
    for name in names:
        spec = load(name)
        lines = [ln.strip() for ln in spec.equation.strip().splitlines() if ln.strip()]
        shown = "; ".join(lines)
        if len(shown) > 60:
            shown = lines[0][:56] + " ..." if len(lines) == 1 else f"{lines[0][:40]} ... ({len(lines)} equations)"
        out.append(f"{name:<{width}}  {shown}")
    return out


def _fmt(x: float) -> str:
    return f"{x:g}"


def report_lines(system, spec, report) -> list[str]:
    """The text `fitode check` prints, as lines."""
    out: list[str] = []
    wrap = textwrap.TextWrapper(width=_WIDTH, subsequent_indent="  ", break_on_hyphens=False)
    if spec is not None:
        out += wrap.wrap(f"{spec.name}: {spec.description}" if spec.description else spec.name)
        if spec.path:
            out.append(f"  file: {spec.path}")
        out.append("")
    text_lines = [ln.strip() for ln in system.text.strip().splitlines() if ln.strip()] or [system.text]
    label = "equation" if len(text_lines) == 1 else "equations"
    out.append(f"{label}:")
    out += [f"  {ln}" for ln in text_lines]
    out.append("normal form:")
    out += [f"  {ln}" for ln in system.normal_form()]
    out.append(f"states ({system.dim} latent dimension{'s' if system.dim != 1 else ''}):")
    width = max(len(s) for s in system.states)
    for s in system.states:
        k = system.orders[s]
        needs = ", ".join(s + "'" * i for i in range(k))
        out.append(f"  {s:<{width}}  order {k}  (the initial state needs {needs})")
    out.append("fixed constants:" if system.fixed else "fixed constants: none")
    if system.fixed:
        width = max(len(n) for n in system.fixed)
        out += [f"  {n:<{width}} = {_fmt(v)}" for n, v in system.fixed.items()]
    out.append("learnable constants:" if system.learnable else "learnable constants: none")
    params = spec.parameters if spec is not None else {}
    if system.learnable:
        width = max(len(n) for n in system.learnable)
        for n in system.learnable:
            p = params.get(n)
            bits = []
            if p is not None:
                if p.init is not None:
                    bits.append(f"init {_fmt(p.init)}")
                if p.min is not None or p.max is not None:
                    lo = _fmt(p.min) if p.min is not None else "-inf"
                    hi = _fmt(p.max) if p.max is not None else "inf"
                    bits.append(f"bounds [{lo}, {hi}]")
                if p.unit:
                    bits.append(f"unit {p.unit}")
            out.append(f"  {n:<{width}}  {', '.join(bits)}".rstrip())
    out += hint_lines(system)
    if spec is not None:
        out.append(f"prior on the latent: N({_fmt(spec.prior_mean)}, {_fmt(spec.prior_std)}^2)"
                   + (f"; suggested stride {spec.stride}" if spec.stride else ""))
    out.append("what a video can measure:")
    body = textwrap.TextWrapper(width=_WIDTH, break_on_hyphens=False)
    for line in report.lines():
        stripped = line.lstrip()
        indent = "  " + line[: len(line) - len(stripped)]
        body.initial_indent = body.subsequent_indent = indent
        out += body.wrap(stripped)
    out += gauge_lines(system)
    out += observation_lines(system, spec.observe if spec is not None else None)
    return out


def observation_lines(system, named: str | dict[str, str] | None) -> list[str]:
    """Which observation model a fit of this equation uses and the degeneracies it removes (the
    catalog's lines and auto rule, fitode.train.observe.catalog)."""
    from fitode.train.observe.catalog import AUTO, MODELS, auto_rule
    if isinstance(named, dict):
        text = [f"{state}: {name} (from the equation file): {MODELS[name].line}" for state, name in named.items()]
    elif named is not None and named != AUTO:
        text = [f"{named} (from the equation file): {MODELS[named].line}"]
    else:
        from fitode.eqparse.identify import power_symmetric
        text = auto_rule(power_symmetric(system))
    out = ["observation (what the camera measures; --observe overrides):"]
    for para in text:
        out += textwrap.wrap(para, width=_WIDTH, initial_indent="  ", subsequent_indent="    ")
    return out

