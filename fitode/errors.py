"""Public home of the error types (defined in the lowest layer so nothing imports upward)."""
from fitode.eqparse.errors import EquationError, FitodeError

__all__ = ["EquationError", "FitodeError"]
