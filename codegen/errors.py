"""Errors raised by code generation and by the physics block (all FitodeError: one line each)."""
from __future__ import annotations

from fitode.eqparse.errors import FitodeError


class CodegenError(FitodeError):
    """The equation cannot be turned into torch code (an unknown function, a complex constant)."""


class ParameterError(FitodeError):
    """A constant's initial value, bounds or requested value is unusable."""


class NonFiniteError(FitodeError):
    """A rollout produced NaN or inf. The message names the first sub-expression that did.

    term: the sub-expression as the user wrote it (e.g. "sqrt(h)"), or a state slot ("x'")
        when the state itself overflowed, or a constant name.
    frame: output frame index at which it happened (None when it was before the rollout).
    window: index into the flattened batch of the first offending element (None if n/a).
    values: the inputs of that term at that element, name -> float.
    """

    def __init__(self, message: str, *, term: str | None = None, frame: int | None = None,
                 window: int | None = None, values: dict[str, float] | None = None):
        super().__init__(message)
        self.term = term
        self.frame = frame
        self.window = window
        self.values = dict(values or {})
