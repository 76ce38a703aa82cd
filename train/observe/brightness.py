"""The brightness observation: the latent is affine in the pixels' linear light."""
from __future__ import annotations

from dataclasses import replace

import torch

from fitode.errors import ConfigError

from ..config import LIGHT_CHOICES
from .base import ObservationModel, Prepared
from .light import CurveChoice, choose_curve, srgb_to_linear


class BrightnessObservation(ObservationModel):
    """The camera measures light: the latent is affine in the pixels' linear light.

    Video stores sRGB-encoded values (about I**(1/2.2)); a latent linear in them reads a decay
    rate 2.2 times too slow. This model decodes to linear light first (light="srgb"; "linear" for
    frames already proportional to light: raw sensor data, a synthetic rendering; "auto", the
    default: whichever makes the change one pattern, light.choose_curve, decided by `settle`),
    then reads the signal subspace with a linear encoder, which can neither bend the latent (an
    MLP could report I**p, decaying at p times the rate) nor draw it out of pixel noise.
    """

    name = "brightness"
    architecture = "linear"

    def __init__(self, light: str = "auto", subspace: bool = True):
        super().__init__(subspace)
        if light not in LIGHT_CHOICES:
            raise ConfigError(f"unknown light {light!r}; choose one of {', '.join(LIGHT_CHOICES)}")
        self.light = light
        self.curve: CurveChoice | None = None  # the frames' verdict on the curve, when light was "auto"

    def settle(self, frames: torch.Tensor) -> None:
        """Decide light "auto" on the training frames (T, C, H, W): once, before any prepare."""
        if self.light == "auto":
            self.curve = choose_curve(frames)
            self.light = self.curve.light

    @property
    def light_reason(self) -> str:
        """One line for the header: how pixel values are read, and why."""
        if self.curve is not None:
            return self.curve.reason
        return ("srgb (as asked: pixel values decoded to linear light)" if self.light == "srgb"
                else "linear (as asked: pixel values read as linear light)")

    def applies(self, check: str) -> bool:
        # decoded light cannot follow only a transient: where it slows, the light does (a decay
        # near rest, which still changes many pixels)
        return False if check == "quiet" else super().applies(check)

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        self.settle(frames[:fit_frames])
        out = super().prepare(self.decoded(frames), architecture, fit_frames)
        how = "decoded from sRGB to linear light" if self.light == "srgb" else "read as linear light (light=linear)"
        caution = self.curve.caution if self.curve is not None else None
        if caution and out.caution:
            caution = f"{out.caution}; {caution}"
        return replace(out, note=f"pixels {how}; {out.note}", caution=caution or out.caution)

    def decoded(self, frames: torch.Tensor) -> torch.Tensor:
        if self.light == "linear":
            return frames
        lo, hi = float(frames.min()), float(frames.max())
        if lo < 0 or hi > 255:
            raise ConfigError(f"the brightness observation decodes sRGB pixel values in [0, 1] or 0..255, but these "
                              f"run from {lo:g} to {hi:g}; give light='linear' (--light linear) for other units")
        return srgb_to_linear(frames / 255.0 if hi > 1.0 else frames)
