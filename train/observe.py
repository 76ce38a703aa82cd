"""Observation models: what the camera measures about the state, and the encoder that reads it.

An observation model owns the whole path from raw frames to latent: `prepare` turns the frames
into what the encoder reads (once per fit), `encoder` builds the (batched) encoder for R
restarts, and `regulariser` may add a term to the loss. The default, "any", is the paper's: a
free encoder (mlp, cnn or linear) on the mean-removed frames, restricted to their signal
subspace. fitode.fit accepts a name or an instance, as PySINDy's estimator accepts its parts.

The signal subspace. An encoder with more free weights than frames can draw any curve out of
pixel noise (a linear encoder on 64x85 frames of a dimming lamp gave a decay rate of the wrong
sign). The frames are projected on their leading principal components first. Where the
singular values drop by a clear gap (one ratio of neighbours above SUBSPACE_JUMP: a lamp that
dims is one component, then video noise), the components above the gap are kept. Otherwise
(a moving object spreads over many components with no gap) those above the noise floor:
SUBSPACE_GAP times the median singular value of the second quarter of the spectrum, where only
noise and the tail of the motion live; at most SUBSPACE_CAP. An mlp or linear encoder then reads the
k coefficients, which is the same function class as reading the projected frames (its first
layer absorbs the projection) at a fraction of the cost; a cnn reads the projected frames.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch

from fitode.errors import ConfigError
from fitode.video.light import srgb_to_linear

from .config import LIGHT_CHOICES, OBSERVE_CHOICES
from .encoders import BatchedEncoder, normalise_frames

SUBSPACE_GAP = 3.0
SUBSPACE_JUMP = 3.0
SUBSPACE_CAP = 32
SCORE_COMPONENTS = 8


@dataclass
class Prepared:
    """The frames as the encoder reads them, and what the checks need from the same analysis."""

    inputs: torch.Tensor  # (T, C, H, W) or (T, k, 1, 1)
    components: np.ndarray  # (T, SCORE_COMPONENTS) leading principal-component coefficients
    rank: int
    note: str  # one line: the subspace kept and why


class ObservationModel:
    """The paper's observation: any function of the pixels the encoder can learn."""

    name = "any"
    architecture: str | None = None  # the encoder it needs; None: any (--encoder decides)

    def __init__(self, subspace: bool = True):
        self.subspace = subspace
        self.reason = ""  # one line: why this model (set by resolve_observation)

    def prepare(self, frames: torch.Tensor, architecture: str = "mlp", fit_frames: int | None = None) -> Prepared:
        """Raw float frames (T, C, H, W) -> what the encoder reads. The principal components come
        from the first fit_frames frames (the training range) only."""
        x = normalise_frames(frames)
        n_fit = x.shape[0] if fit_frames is None else int(fit_frames)
        flat = x.reshape(x.shape[0], -1).double()
        mean = flat[:n_fit].mean(dim=0, keepdim=True)
        centred = flat - mean
        fit = centred[:n_fit]
        evals, evecs = torch.linalg.eigh(fit @ fit.T)  # the T x T Gram matrix is small where pixels are many
        order = torch.argsort(evals, descending=True)
        sv = evals[order].clamp_min(0).sqrt()
        k_max = int((sv > 1e-9 * sv[0]).sum()) if sv[0] > 0 else 0
        floor = float(sv[len(sv) // 4: max(len(sv) // 2, len(sv) // 4 + 1)].median()) if len(sv) >= 8 else 0.0
        above = int((sv > SUBSPACE_GAP * floor).sum()) if floor > 0 else k_max
        head = sv[: min(SUBSPACE_CAP, k_max) + 1]
        jumps = (head[:-1] / head[1:].clamp_min(1e-300)) if len(head) > 1 else head[:0]
        jump = int(torch.argmax(jumps)) if len(jumps) else -1
        gapped = jump >= 0 and float(jumps[jump]) > SUBSPACE_JUMP
        rank = (jump + 1) if gapped else max(1, min(above, SUBSPACE_CAP, k_max)) if k_max else 1
        # pixel directions of the leading components: V = X^T U / s
        keep = order[: max(rank, SCORE_COMPONENTS)]
        u = evecs[:, keep]
        s = sv[: keep.numel()].clamp_min(1e-12)
        basis = (fit.T @ u) / s  # (pixels, K), orthonormal columns
        coefs = centred @ basis  # (T, K): every frame, the held-out ones too
        components = coefs[:, :SCORE_COMPONENTS].cpu().numpy()
        if not self.subspace:
            return Prepared(x, components, k_max, "the encoder reads every pixel (no signal subspace)")
        plural = "s" if rank != 1 else ""
        if gapped:
            note = (f"signal subspace: {rank} principal component{plural} of the frames (the singular values "
                    f"drop {_times(float(jumps[jump]))} after the {rank}{_th(rank)})")
        else:
            ratio = f"{float(sv[rank - 1] / floor):.1f}x" if floor > 0 else "n/a"
            note = (f"signal subspace: {rank} principal component{plural} of the frames "
                    + (f"(capped at {SUBSPACE_CAP}; " if above > SUBSPACE_CAP else "(")
                    + f"the last kept stands {ratio} above the noise floor)")
        head = coefs[:, :rank]
        if architecture == "cnn":
            inputs = (head @ basis[:, :rank].T + mean).reshape(x.shape).to(x.dtype)
        else:
            inputs = (head / s[0] * np.sqrt(n_fit)).to(x.dtype).reshape(x.shape[0], rank, 1, 1)
        return Prepared(inputs, components, rank, note)

    def encoder(self, architecture: str, in_shape: tuple[int, int, int], dim: int, seeds,
                output_mean: float = 0.0) -> BatchedEncoder:
        return BatchedEncoder(architecture, in_shape, dim, seeds, output_mean=output_mean)

    def regulariser(self, z: torch.Tensor) -> torch.Tensor | None:
        """An extra loss term per restart, (R,), from the latents z (R, N, d); None for none."""
        return None


def _times(ratio: float) -> str:
    return "over 1000x" if ratio > 1000 else f"{ratio:.0f}x"


def _th(k: int) -> str:
    return {1: "st", 2: "nd", 3: "rd"}.get(k if k < 20 else k % 10, "th")


class BrightnessObservation(ObservationModel):
    """The camera measures light: the latent is affine in the pixels' linear light.

    Video stores sRGB-encoded values (about I**(1/2.2)); a latent linear in them reads a decay
    rate 2.2 times too slow. This model decodes to linear light first (light="srgb", the default;
    "linear" for frames already proportional to light: raw sensor data, a synthetic rendering),
    then reads the signal subspace with a linear encoder, which can neither bend the latent (an
    MLP could report I**p, decaying at p times the rate) nor draw it out of pixel noise.
    """

    name = "brightness"
    architecture = "linear"

    def __init__(self, light: str = "srgb", subspace: bool = True):
        super().__init__(subspace)
        if light not in LIGHT_CHOICES:
            raise ConfigError(f"unknown light {light!r}; choose one of {', '.join(LIGHT_CHOICES)}")
        self.light = light

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        out = super().prepare(self.decoded(frames), architecture, fit_frames)
        how = "decoded from sRGB to linear light" if self.light == "srgb" else "read as linear light (light=linear)"
        return replace(out, note=f"pixels {how}; {out.note}")

    def decoded(self, frames: torch.Tensor) -> torch.Tensor:
        if self.light == "linear":
            return frames
        lo, hi = float(frames.min()), float(frames.max())
        if lo < 0 or hi > 255:
            raise ConfigError(f"the brightness observation decodes sRGB pixel values in [0, 1] or 0..255, but these "
                              f"run from {lo:g} to {hi:g}; give light='linear' (--light linear) for other units")
        return srgb_to_linear(frames / 255.0 if hi > 1.0 else frames)


OBSERVATIONS = {"any": ObservationModel, "brightness": BrightnessObservation}
assert ("auto",) + tuple(OBSERVATIONS) == OBSERVE_CHOICES, "train/config.py lists the models the CLI offers"

# The auto choice: of the change the frames' first principal component carries, the share whose
# sign agrees with the whole (energy-weighted). A lamp that dims darkens every pixel it lights
# (near 1); an object that moves darkens where it leaves and lightens where it arrives (near 0).
ONE_SIGNED = 0.8
LOOK_FRAMES = 256


def resolve_observation(spec: str | ObservationModel | None, system, frames: torch.Tensor | None = None,
                        light: str = "srgb", encoder: str = "auto") -> ObservationModel:
    """The observation model a fit uses, with its reason: an instance as given, a name, or "auto"
    (None): brightness for a single first-order linear equation whose frames brighten or dim as
    one, any otherwise (and wherever an encoder other than linear was asked for)."""
    if isinstance(spec, ObservationModel):
        spec.reason = spec.reason or f"{spec.name} (as given)"
        return spec
    name = "auto" if spec is None else spec
    if name not in OBSERVE_CHOICES:
        raise ConfigError(f"unknown observation model {name!r}; choose one of {', '.join(OBSERVE_CHOICES)}")
    if name != "auto":
        model = BrightnessObservation(light) if name == "brightness" else ObservationModel()
        model.reason = f"{name} (as asked)"
        return model
    if encoder not in ("auto", "linear"):
        model = ObservationModel()
        model.reason = f"any (auto: the {encoder} encoder was asked for)"
        return model
    from fitode.eqparse.identify import power_symmetric  # sympy: only when a fit is set up
    if not power_symmetric(system):
        model = ObservationModel()
        model.reason = "any (auto: the paper's free encoder; the equation's constants do not follow a bend of the latent)"
        return model
    share = one_signed_share(frames) if frames is not None else 0.0
    if share >= ONE_SIGNED:
        model = BrightnessObservation(light)
        model.reason = (f"brightness (auto: a single first-order linear equation, and the frames brighten or dim as "
                        f"one: {share:.0%} of the change has one sign)")
    else:
        model = ObservationModel()
        model.reason = (f"any (auto: the change has both signs, {share:.0%} one-signed, as where something moves; "
                        "the linear encoder keeps the rate)")
    return model


@torch.no_grad()
def one_signed_share(frames: torch.Tensor) -> float:
    """How much of the frames' main change has one sign (0.5..1; see ONE_SIGNED), from at most
    LOOK_FRAMES frames spread over the clip."""
    step = max(1, frames.shape[0] // LOOK_FRAMES)
    sub = frames[::step]
    flat = sub.reshape(sub.shape[0], -1).double()
    centred = flat - flat.mean(dim=0, keepdim=True)
    if centred.shape[0] < 2 or float(centred.abs().max()) == 0:
        return 0.0
    _, vecs = torch.linalg.eigh(centred @ centred.T)
    v = centred.T @ vecs[:, -1]  # the first component's pixel map (its overall sign is arbitrary)
    energy = v * v
    positive = float(energy[v > 0].sum())
    return max(positive, float(energy.sum()) - positive) / float(energy.sum())
