"""fitode: the unknown constants of a known ODE, from a video."""
__version__ = "0.1.0"
