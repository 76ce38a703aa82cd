"""Errors shared by every layer. They live in the lowest layer so nothing imports upward."""


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
