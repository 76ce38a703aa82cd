"""The camera's transfer curve: video stores sRGB-encoded values, not light.

A phone or webcam writes roughly I**(1/2.2) (the sRGB curve: linear near black, a 2.4 power
above). A latent that is linear in the encoded pixels measures that power of the light, and a
decay rate read from it is off by the same factor, so the brightness observation decodes first.
Both functions take numpy arrays or torch tensors with values in [0, 1] and clip to that range.
"""
from __future__ import annotations


def srgb_to_linear(v):
    """Encoded values in [0, 1] -> linear light in [0, 1] (IEC 61966-2-1)."""
    v = v.clip(0.0, 1.0)
    dark = v <= 0.04045
    return dark * (v / 12.92) + ~dark * ((v + 0.055) / 1.055) ** 2.4


def linear_to_srgb(v):
    """Linear light in [0, 1] -> encoded values in [0, 1], what a camera writes."""
    v = v.clip(0.0, 1.0)
    dark = v <= 0.0031308
    return dark * (v * 12.92) + ~dark * (1.055 * v ** (1 / 2.4) - 0.055)
