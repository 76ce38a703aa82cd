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
# A lamp's change in linear light is one pattern times one brightness: after the first singular
# value of the frames (their mean taken out) the spectrum sits at the noise floor. Read through
# the wrong curve, the same change bends into a second pattern that stands above it. The second
# singular value over the third measures that; the reading whose ratio is clearly lower wins.
TELLS = 1.25  # the wrong reading's ratio over the right one's: below this the frames cannot tell
LOOK = 256    # frames spread over the clip that the choice looks at


@dataclass(frozen=True)
class CurveChoice:
    """How the brightness observation reads pixel values: light "srgb" or "linear"; told: the
    frames decided it (not a default); reason: one line for the header; caution: where the
    frames could not tell, the line for the verdict."""

    light: str
    told: bool
    reason: str
    separation: dict[str, float]
    caution: str | None = None


def second_component(frames) -> float:
    """The frames' (T, ...) second singular value over their third, their mean over time taken
    out: about 1 where the change is one pattern (the rest is noise), above where it is two."""
    import torch

    x = torch.as_tensor(frames).double().reshape(len(frames), -1)
    x = x - x.mean(dim=0)
    sv = torch.linalg.eigvalsh(x @ x.T).flip(0).clamp_min(0).sqrt()
    if len(sv) < 3 or float(sv[2]) <= 0:
        return float("inf") if len(sv) >= 3 and float(sv[1]) > 0 else 1.0
    return float(sv[1] / sv[2])


def choose_curve(frames) -> CurveChoice:
    """The camera's transfer curve from the frames (T, C, H, W) in [0, 1] or 0..255: sRGB-encoded
    or linear light, whichever makes the change one pattern (see TELLS). Where the frames cannot
    tell (a uniform patch brightens the same way through any curve), sRGB, as phones store it,
    with a caution: the rate read depends on the curve."""
    lo, hi = float(frames.min()), float(frames.max())
    if lo < 0 or hi > 255:
        return CurveChoice("linear", True, f"linear (the values run from {lo:g} to {hi:g}: not pixel values)", {})
    step = max(1, len(frames) // LOOK)
    sub = frames[::step]
    sub = sub / 255.0 if hi > 1.0 else sub
    sep = {"linear": second_component(sub), "srgb": second_component(srgb_to_linear(sub))}
    best, other = sorted(sep, key=sep.get)
    said = f"second singular value over the third: {sep['linear']:.2f} read as linear light, {sep['srgb']:.2f} decoded from sRGB"
    if sep[other] >= TELLS * sep[best]:
        what = "linear light" if best == "linear" else "sRGB-encoded"
        return CurveChoice(best, True, f"{best} (the frames store {what}: read so, the change is one pattern; "
                           f"{said})", sep)
    caution = ("the frames cannot tell whether the camera stores sRGB or linear light (the change is one pattern "
               "either way): the rate assumes sRGB; read as linear light it would be smaller by up to the curve's "
               "power (about 2.4x); give --light to say which")
    return CurveChoice("srgb", False, f"srgb (assumed, as phones store it: the frames cannot tell; {said})", sep,
                       caution)
