"""Public home of the error types (defined in the lowest layer so nothing imports upward)."""
from fitode.codegen.errors import NonFiniteError
from fitode.eqparse.errors import EquationError, FitodeError

__all__ = ["EquationError", "FitodeError", "NonFiniteError"]
