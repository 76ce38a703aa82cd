"""The camera's transfer curve: video stores sRGB-encoded values, not light.

A phone or webcam writes roughly I**(1/2.2) (the sRGB curve: linear near black, a 2.4 power
above). A latent that is linear in the encoded pixels measures that power of the light, and a
decay rate read from it is off by the same factor, so the brightness observation decodes first.
Both functions take numpy arrays or torch tensors with values in [0, 1] and clip to that range.
`choose_curve` tells from the frames which curve a camera stored (light "auto", the default).
"""
from __future__ import annotations

from dataclasses import dataclass


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


# --- which curve the frames were stored with --------------------------------------------------
# A lamp's change in linear light is one pattern times one brightness: take the first pattern
# out of the frames (their mean over time taken out) and what is left is noise. Read through the
# wrong curve, each pixel bends its own way with the brightness, and what is left leans along the
# square of the first pattern's time course (a curve's second-order term). What is left along
# that one direction, coherent over the frames, over what noise independent from frame to frame
# would put there (each frame's own energy left, so noise that grows with the light does not
# count as a bend), measures the bend; the reading that bends clearly less wins. One direction
# is a sharper test than the second singular value over the third, which the codec's own
# patterns swamp: on 24 generated lamps (bench/coverage.py's led and led-linear draws, seeds
# 0-2, as the default reading shrinks them to gray), the wrong reading bent 1.5-6x more than the
# right one; the second singular value over the third told them 1.0-1.9x apart.
TELLS = 1.4      # the wrong reading's bend over the right one's: below this the frames cannot tell
LOOK = 256       # frames spread over the clip that the choice looks at
CHANGING = 0.3   # pixels whose spread over time reaches this share of the largest: the lamp's light


@dataclass(frozen=True)
class CurveChoice:
    """How the brightness observation reads pixel values: light "srgb" or "linear"; told: the
    frames decided it (not a default); reason: one line for the header; separation: each
    reading's bend (about 1 where the change is one pattern); caution: where the frames could
    not tell, the line for the verdict."""

    light: str
    told: bool
    reason: str
    separation: dict[str, float]
    caution: str | None = None


def bend(frames) -> float:
    """How far the frames (T, ...) are from one pattern times one time course, where they change:
    the energy left after the first pattern along the square of its time course, over what noise
    independent from frame to frame puts along it. About 1 for one pattern plus noise; large where
    every pixel bends the same time course its own way (light read through the wrong curve)."""
    import numpy as np

    x = np.asarray(frames, dtype=np.float64).reshape(len(frames), -1)
    if x.shape[0] < 8:
        return 1.0
    spread = x.std(axis=0)
    if not spread.max() > 0:
        return 1.0
    x = x[:, spread >= CHANGING * spread.max()]
    x = x - x.mean(axis=0)
    u = np.linalg.eigh(x @ x.T)[1][:, -1]   # the first pattern's time course
    left = x - np.outer(u, u @ x)
    rows = np.sum(left * left, axis=1)  # each frame's energy left: noise that may change with the light

    def along(d):
        d = d - d.mean()
        d = d - u * (u @ d)
        norm = np.linalg.norm(d)
        if not norm > 0:
            return 1.0
        d = d / norm
        incoherent = float(np.sum(d * d * rows))  # what noise independent from frame to frame puts there
        return float(np.sum((d @ left) ** 2)) / incoherent if incoherent > 0 else 1.0

    return along(u * u)


def choose_curve(frames) -> CurveChoice:
    """The camera's transfer curve from the frames (T, C, H, W) in [0, 1] or 0..255: sRGB-encoded
    or linear light, whichever bends the change less (see TELLS). Where the frames cannot tell (a
    uniform patch brightens the same way through any curve), sRGB, as phones store it, with a
    caution: the rate read depends on the curve."""
    lo, hi = float(frames.min()), float(frames.max())
    if lo < 0 or hi > 255:
        return CurveChoice("linear", True, f"linear (the values run from {lo:g} to {hi:g}: not pixel values)", {})
    step = max(1, len(frames) // LOOK)
    sub = frames[::step]
    sub = sub / 255.0 if hi > 1.0 else sub
    sep = {"linear": bend(sub), "srgb": bend(srgb_to_linear(sub))}
    best, other = sorted(sep, key=sep.get)
    said = (f"what the first pattern leaves bends {sep['linear']:.2f}x the noise read as linear light, "
            f"{sep['srgb']:.2f}x decoded from sRGB")
    if sep[other] >= TELLS * sep[best]:
        what = "linear light" if best == "linear" else "sRGB-encoded"
        return CurveChoice(best, True, f"{best} (the frames store {what}: read so, the change is one pattern; "
                           f"{said})", sep)
    caution = ("the frames cannot tell whether the camera stores sRGB or linear light (the change is one pattern "
               "either way): the rate assumes sRGB; read as linear light it would be smaller by up to the curve's "
               "power (about 2.4x); give --light to say which")
    return CurveChoice("srgb", False, f"srgb (assumed, as phones store it: the frames cannot tell; {said})", sep,
                       caution)
