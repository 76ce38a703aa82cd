"""The brightness observation: the latent is affine in the pixels' linear light."""
from __future__ import annotations

from dataclasses import replace

import torch

from fitode.errors import ConfigError

from ..config import LIGHT_CHOICES
from .base import ObservationModel, Prepared
from .light import CurveChoice, choose_curve, srgb_to_linear

# the light is read where it changes by at least this share of the most (a pixel's spread over the
# fit frames): a lamp's wide faint wash changes by a few codec steps, and a lossy codec holds such
# small changes back (it skips blocks that change little), so the wash decays late. Read with it,
# the generated LED's rate came out 6.6% low (linear) and 6.3% (sRGB) from one component whose
# exponential fits 0.874 on the decoded file at full size against 0.911 on the frames before the
# codec; read where the change is strong, 0.91 from either file.
LIGHT_REGION = 0.2


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
        self.one_path = False  # the encoder reads one principal component linearly (set by prepare)

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

    # a camera's curve is sRGB only roughly and a codec holds back small changes (a faint change
    # decays late), so light read linearly is off by more than its residuals show: fitted
    # directly, 16 of 16 generated lamps came out 0.3-2% slow with residual intervals of
    # +-0.5-1.5% (1 to 3 of 16 outside their 99% interval in `bench/coverage.py --cases
    # led,led-linear`). The bends' share, at least this much of the rate, holds them.
    bend_floor = 0.01
    # light follows its equation to the end: a decay's slow tail is no stop, and a short stretch of
    # it pins the rate badly (a 16x16 lamp cut where its tail flattened at 1.3 s: gamma 0.303 for
    # 0.4, trusted; over the whole clip 0.397)
    no_stretch = "a light's slow tail is its equation's own, no stop: no stretch is looked for"

    @property
    def can_bend(self) -> bool:
        return True

    @property
    def may_measure(self) -> bool:
        return True

    @property
    def reads_lengths(self) -> bool:
        return False  # light has no length: no pixels or metres to say

    def applies(self, check: str) -> bool:
        # decoded light cannot follow only a transient: where it slows, the light does (a decay
        # near rest, which still changes many pixels). A linear read of one principal component is
        # one path for every restart up to its scale and offset, as a measured latent is: the
        # restarts the loss leaves out fitted that path worse, not in another basin, so no score
        # (and no rival restarts) is taken (a lamp's restarts at 1.5962, 1.5963 and 1.5967 with
        # losses 1.1, 0.84 and 0.11, and one stopped at the step limit at 1.5126, made it ambiguous)
        if check in ("quiet", "stretch") or (check == "score" and self.one_path):
            return False
        return super().applies(check)

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        self.settle(frames[:fit_frames])
        out = super().prepare(where_light_changes(self.decoded(frames), fit_frames), architecture, fit_frames)
        self.one_path = architecture == "linear" and out.rank == 1 and self.subspace
        # one component read linearly is a measured path in arbitrary units, as a size is in
        # pixels: the trajectory fitter takes it directly (train/direct.py), with the checks of a
        # measured path, instead of training an encoder to learn only its scale and offset
        self.measured = self.one_path
        if self.one_path and self.equation_states:
            out = replace(out, states=self.equation_states[:1])
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


def where_light_changes(frames: torch.Tensor, fit_frames: int | None = None) -> torch.Tensor:
    """The frames (T, C, H, W) with every pixel whose spread over the first fit_frames stays under
    LIGHT_REGION of the largest held at its mean there (it then adds nothing to the principal
    components): the light is read where it changes clearly."""
    n_fit = frames.shape[0] if fit_frames is None else int(fit_frames)
    fit = frames[:n_fit].double()
    spread = fit.std(dim=0).mean(dim=0)  # (H, W)
    top = float(spread.max()) if spread.numel() else 0.0
    if not top > 0:
        return frames
    weak = (spread < LIGHT_REGION * top)[None, None]
    return torch.where(weak, fit.mean(dim=0, keepdim=True).to(frames.dtype), frames)
