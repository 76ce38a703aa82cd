"""`fitode codegen`: print the torch code fitode generates for an equation.

    fitode codegen --eq "theta'' = -g/L*sin(theta) - zeta*theta'"
    fitode codegen --system pendulum --integrator symplectic --init backward

The printed module is exactly the function the physics block compiles (the vector field of the
equation's first-order form), preceded by comments on the integrator's step and on how the
initial state is built from a window's first frames.
"""
from __future__ import annotations

import argparse

from fitode.errors import FitodeError
from fitode.names import parse_assignments
from fitode.options import add_equation_arguments, positive_int
from fitode.train.config import INTEGRATOR_NAMES


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_equation_arguments(p)
    gen = p.add_argument_group("what to describe")
    gen.add_argument("--integrator", default="rk4", choices=[*INTEGRATOR_NAMES, "paper"],
                     help="integrator whose step is described (default rk4; paper = symplectic)")
    gen.add_argument("--substeps", type=positive_int, default=1, metavar="N", help="sub-steps per frame (default 1)")
    gen.add_argument("--init", default="difference", choices=["difference", "backward", "learnable"],
                     help="how the initial state is built from the first frames (default difference)")
    gen.add_argument("--context", type=positive_int, metavar="N",
                     help="frames used for the initial state (default: by --init)")


def _assignments(items: list[str]) -> dict[str, float]:
    return parse_assignments(items, "--const")


def resolve_system(args: argparse.Namespace):
    """The OdeSystem named by --eq / --system / --eq-file (with --const / --free)."""
    const = _assignments(args.const)
    try:
        from fitode.eqfile import resolve
    except ImportError:
        resolve = None
    if resolve is not None:
        system, _spec = resolve(eq=args.eq, eq_file=args.eq_file, system=args.system, const=const,
                                free=tuple(args.free))
        return system
    if args.eq is None:
        raise FitodeError("equation files are not available in this installation; use --eq TEXT")
    from fitode.eqparse import parse
    return parse(args.eq, fix=const, free=args.free)


def run(args: argparse.Namespace) -> int:
    from fitode.codegen import generate_source

    system = resolve_system(args)
    print(generate_source(system, integrator=args.integrator, substeps=args.substeps, initial_state=args.init,
                          context=args.context), end="")
    return 0
