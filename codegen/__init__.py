"""OdeSystem -> differentiable torch physics block.

    from fitode.codegen import PhysicsBlock, generate_source, simulate, INTEGRATORS

The equation's right-hand sides are printed to Python by sympy's torch printer
(fitode.codegen.source), compiled once per normalised equation, and wrapped in a first-order
form (fitode.codegen.layout). Integrators (euler, symplectic = the paper's scheme, rk4) live in
fitode.codegen.integrators; initial states from finite differences in
fitode.codegen.differences; bounds and lr scales of constants in fitode.codegen.constants; the
non-finite guard in fitode.codegen.guard.
"""
from .block import PhysicsBlock, simulate
from .constants import Reparam
from .differences import INIT_MODES, InitScheme, describe_init, init_scheme
from .errors import CodegenError, NonFiniteError, ParameterError
from .integrators import INTEGRATORS, RK4, Euler, Integrator, SymplecticEuler, get_integrator
from .layout import Slot, StateLayout
from .source import VectorField, compile_system, generate_source

__all__ = [
    "PhysicsBlock", "simulate", "generate_source", "compile_system", "VectorField",
    "INTEGRATORS", "Integrator", "Euler", "SymplecticEuler", "RK4", "get_integrator",
    "INIT_MODES", "InitScheme", "init_scheme", "describe_init", "StateLayout", "Slot", "Reparam",
    "CodegenError", "NonFiniteError", "ParameterError",
]
