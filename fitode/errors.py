"""Every error fitode raises, in one leaf module that imports nothing.

Each is a FitodeError: a problem with the user's input or run that the command line reports in
one line (status 2). Lower layers (eqparse, codegen, train) import their errors from here, so
`import fitode.errors` never loads torch or sympy.
"""


class FitodeError(Exception):
    """A problem with the user's input or run that the command line reports in one line."""


class EquationError(FitodeError):
    """A malformed or unusable equation. `column` is 1-based, or None when no column applies."""

    def __init__(self, message: str, column: int | None = None, text: str | None = None):
        self.message = message
        self.column = column
        self.text = text
        super().__init__(self.__str__())

    def __str__(self) -> str:
        if self.column is None:
            return self.message
        return f"{self.message} (column {self.column})"


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


class ConfigError(FitodeError):
    """A training option is unknown or has an unusable value; the message names the option."""


class TrainingError(FitodeError):
    """Training could not produce an estimate (every run failed, too few frames, ...)."""


__all__ = ["CodegenError", "ConfigError", "EquationError", "FitodeError", "NonFiniteError", "ParameterError",
           "TrainingError"]
