"""The camera's transfer curve, for video reading and synthetic scenes: it lives with the
brightness observation that decodes it (fitode.train.observe.light)."""
from fitode.train.observe.light import linear_to_srgb, srgb_to_linear

__all__ = ["linear_to_srgb", "srgb_to_linear"]
