"""Observation models: what the camera measures about the state, and the encoder that reads it.

An observation model owns the whole path from raw frames to latent: `prepare` normalises the
frames once per fit, `encoder` builds the (batched) encoder for R restarts, and `regulariser`
may add a term to the loss. The default, "any", is the paper's: a free encoder (mlp, cnn or
linear) on the mean-removed frames. fitode.fit accepts a name or an instance, as PySINDy's
estimator accepts its parts.
"""
from __future__ import annotations

import torch

from fitode.errors import ConfigError

from .encoders import BatchedEncoder, normalise_frames


class ObservationModel:
    """The paper's observation: any function of the pixels the encoder can learn."""

    name = "any"

    def prepare(self, frames: torch.Tensor) -> torch.Tensor:
        """Raw float frames (T, C, H, W) -> what the encoder reads."""
        return normalise_frames(frames)

    def encoder(self, architecture: str, in_shape: tuple[int, int, int], dim: int, seeds,
                output_mean: float = 0.0) -> BatchedEncoder:
        return BatchedEncoder(architecture, in_shape, dim, seeds, output_mean=output_mean)

    def regulariser(self, z: torch.Tensor) -> torch.Tensor | None:
        """An extra loss term per restart, (R,), from the latents z (R, N, d); None for none."""
        return None


OBSERVATIONS = {"any": ObservationModel}


def observation_model(spec: str | ObservationModel | None) -> ObservationModel:
    if spec is None:
        return ObservationModel()
    if isinstance(spec, ObservationModel):
        return spec
    if spec not in OBSERVATIONS:
        raise ConfigError(f"unknown observation model {spec!r}; choose one of {', '.join(OBSERVATIONS)}")
    return OBSERVATIONS[spec]()
