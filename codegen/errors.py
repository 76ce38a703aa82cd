"""Errors raised by code generation and by the physics block; defined in the leaf module fitode.errors."""
from fitode.errors import CodegenError, NonFiniteError, ParameterError

__all__ = ["CodegenError", "NonFiniteError", "ParameterError"]
