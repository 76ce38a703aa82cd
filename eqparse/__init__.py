"""Equation text -> checked OdeSystem (lark grammar, sympy)."""
from .errors import EquationError, FitodeError
from .system import OdeSystem, ParamSpec, deriv_symbol

__all__ = ["EquationError", "FitodeError", "OdeSystem", "ParamSpec", "deriv_symbol"]
