"""Equation text -> checked OdeSystem (lark grammar, sympy)."""
from .errors import EquationError, FitodeError
from .parser import FUNCTIONS, KNOWN_CONSTANTS, MAX_LENGTH, parse
from .system import OdeSystem, ParamSpec, deriv_symbol

__all__ = ["EquationError", "FitodeError", "FUNCTIONS", "KNOWN_CONSTANTS", "MAX_LENGTH", "OdeSystem",
           "ParamSpec", "deriv_symbol", "parse"]
