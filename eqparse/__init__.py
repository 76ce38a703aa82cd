"""Equation text -> checked OdeSystem (lark grammar, sympy)."""
from .errors import EquationError, FitodeError
from .identify import ConstantReport, IdentifiabilityReport, analyse
from .parser import FUNCTIONS, KNOWN_CONSTANTS, MAX_LENGTH, parse
from .system import OdeSystem, ParamSpec, deriv_symbol, format_expr

__all__ = [
    "ConstantReport", "EquationError", "FitodeError", "FUNCTIONS", "IdentifiabilityReport", "KNOWN_CONSTANTS",
    "MAX_LENGTH", "OdeSystem", "ParamSpec", "analyse", "deriv_symbol", "format_expr", "parse",
]
