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
# A lamp's change in linear light is one pattern times one brightness. Read through the wrong
# curve, each pixel bends its own way with the brightness and the change no longer is one
# pattern. Two measures of that bend, each about 1 where the change is one pattern plus noise:
# - `second_component`: the second singular value over the third (a second pattern standing
#   above the rest);
# - `bend`: what the first pattern leaves, along the square of its time course (a curve's
#   second-order term), over what noise independent from frame to frame would put there.
# Neither alone is safe on small frames: on 80 generated lamps (5 sizes from 64x48 to 480x270,
# both curves, bench/lightcurve.py) the bend pointed the wrong way once,
# by 2.5x, on a 64x48 linear lamp whose light changes 29 pixels of the shrunk frames, where the
# singular values pointed the right way; the singular values alone cannot tell most sRGB lamps
# (1.0-1.2x apart). So a curve is told where both point to it and one points clearly.
TELLS = 1.25       # the singular values' ratio (wrong reading over right) that tells by itself
TELLS_BEND = 2.0   # the bend's ratio that tells by itself
FEWEST = 40        # pixels whose change is the lamp's: fewer, and the codec's own bends swamp the curve's
LOOK = 256         # frames spread over the clip that the choice looks at
CHANGING = 0.3     # pixels whose spread over time reaches this share of the largest: the lamp's light


@dataclass(frozen=True)
class CurveChoice:
    """How the brightness observation reads pixel values: light "srgb" or "linear"; told: the
    frames decided it (not a default); reason: one line for the header; separation: each
    reading's second singular value over its third, and its bend (keys "bend_linear",
    "bend_srgb"), each about 1 where the change is one pattern; caution: where the frames could
    not tell, the line for the verdict."""

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


def changing(frames):
    """The frames (T, ...) as (T, pixels) where they change: the pixels whose spread over time
    reaches CHANGING of the largest."""
    import numpy as np

    x = np.asarray(frames, dtype=np.float64).reshape(len(frames), -1)
    spread = x.std(axis=0)
    return x[:, spread >= CHANGING * spread.max()] if spread.max() > 0 else x[:, :0]


def bend(frames) -> float:
    """How far the frames (T, ...) are from one pattern times one time course where they change:
    the energy the first pattern leaves along the square of its time course, over what noise
    independent from frame to frame puts along it (each frame's own energy left, so noise that
    grows with the light does not count as a bend). About 1 for one pattern plus noise."""
    import numpy as np

    x = changing(frames)
    if x.shape[0] < 8 or x.shape[1] == 0:
        return 1.0
    x = x - x.mean(axis=0)
    u = np.linalg.eigh(x @ x.T)[1][:, -1]  # the first pattern's time course
    left = x - np.outer(u, u @ x)
    rows = np.sum(left * left, axis=1)
    d = u * u
    d = d - d.mean()
    d = d - u * (u @ d)
    norm = np.linalg.norm(d)
    if not norm > 0:
        return 1.0
    d = d / norm
    incoherent = float(np.sum(d * d * rows))
    return float(np.sum((d @ left) ** 2)) / incoherent if incoherent > 0 else 1.0


def choose_curve(frames) -> CurveChoice:
    """The camera's transfer curve from the frames (T, C, H, W) in [0, 1] or 0..255: sRGB-encoded
    or linear light, whichever both measures find less bent, one of them clearly (TELLS,
    TELLS_BEND), on at least FEWEST changing pixels. Where the frames cannot tell (a uniform
    patch brightens the same way through any curve), sRGB, as phones store it, with a caution:
    the rate read depends on the curve."""
    lo, hi = float(frames.min()), float(frames.max())
    if lo < 0 or hi > 255:
        return CurveChoice("linear", True, f"linear (the values run from {lo:g} to {hi:g}: not pixel values)", {})
    step = max(1, len(frames) // LOOK)
    sub = frames[::step]
    sub = sub / 255.0 if hi > 1.0 else sub
    decoded = srgb_to_linear(sub)
    sep = {"linear": second_component(sub), "srgb": second_component(decoded),
           "bend_linear": bend(sub), "bend_srgb": bend(decoded)}
    pixels = int(changing(sub).shape[1])
    said = (f"second singular value over the third {sep['linear']:.2f} read as linear light, {sep['srgb']:.2f} "
            f"decoded from sRGB; bend {sep['bend_linear']:.1f} and {sep['bend_srgb']:.1f}; {pixels} pixels change")
    for best, other in (("linear", "srgb"), ("srgb", "linear")):
        by_sv = sep[other] / sep[best]
        by_bend = sep[f"bend_{other}"] / sep[f"bend_{best}"]
        if pixels >= FEWEST and by_sv >= 1 and by_bend >= 1 and (by_sv >= TELLS or by_bend >= TELLS_BEND):
            what = "linear light" if best == "linear" else "sRGB-encoded"
            return CurveChoice(best, True, f"{best} (the frames store {what}: read so, the change is one pattern; "
                               f"{said})", sep)
    caution = ("the frames cannot tell whether the camera stores sRGB or linear light (the change is one pattern "
               "either way): the rate assumes sRGB; read as linear light it would be smaller by up to the curve's "
               "power (about 2.4x); give --light to say which")
    return CurveChoice("srgb", False, f"srgb (assumed, as phones store it: the frames cannot tell; {said})", sep,
                       caution)
