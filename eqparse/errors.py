"""The equation layer's errors; defined in the leaf module fitode.errors."""
from fitode.errors import EquationError, FitodeError

__all__ = ["EquationError", "FitodeError"]
