"""The learned gauge x = s*z + b between latent and state, one (s, b) per restart and state.

Which of s and b is learned comes from the equation (fitode.eqparse.gauge); the fixed ones stay
at 1 and 0 exactly (their gradient is masked off, so Adam never moves them).
"""
from __future__ import annotations

import math
from typing import Mapping

import torch
from torch import nn

from fitode.eqparse.gauge import StateGauge

SCALE_START = 0.2  # a learned scale starts small: a pendulum's small swing, where sin(x) ~ x
LR_FACTOR = 0.2  # the offset's share of the constants' lr: at 0.05 per step it left sqrt's domain in 30 steps


class Gauge(nn.Module):
    def __init__(self, plan: Mapping[str, StateGauge], states, restarts: int, prior: tuple[float, float],
                 enabled: bool = True, dtype: torch.dtype = torch.float32):
        super().__init__()
        self.states = list(states)
        learn_s = [enabled and plan[s].scale_learned for s in self.states]
        learn_b = [enabled and plan[s].offset_learned for s in self.states]
        mean, std = prior
        s0 = [SCALE_START if learn_s[i] else 1.0 for i in range(len(self.states))]
        # a state under sqrt or log starts inside its domain: three latent spreads above zero
        b0 = [s0[i] * (3 * std + max(0.0, -mean)) if (learn_b[i] and plan[st].positive) else 0.0
              for i, st in enumerate(self.states)]
        d = len(self.states)
        self.unit = float(std)  # the offset is learned in units of the latent's spread
        b0 = [v / self.unit for v in b0]
        self.register_buffer("positive", torch.tensor([learn_b[i] and plan[st].positive
                                                      for i, st in enumerate(self.states)], dtype=torch.bool))
        self.register_buffer("learn_scale", torch.tensor(learn_s, dtype=torch.bool))
        self.register_buffer("learn_offset", torch.tensor(learn_b, dtype=torch.bool))
        self.log_scale = nn.Parameter(torch.tensor([math.log(v) for v in s0], dtype=dtype).repeat(restarts, 1))
        self.offset = nn.Parameter(torch.tensor(b0, dtype=dtype).repeat(restarts, 1))
        self.register_buffer("log_scale0", self.log_scale.detach().clone())
        self.register_buffer("offset0", self.offset.detach().clone())
        assert self.log_scale.shape == (restarts, d)

    @torch.no_grad()
    def enter_domain(self, z: torch.Tensor) -> None:
        """Raise the offsets of states under sqrt/log until every frame's state is positive, for
        the encoder's first latents z (R, T, d): the prior holds their spread only after training
        has begun, and an untrained encoder's outputs spread wider."""
        if not bool(self.positive.any()):
            return
        s, b = self.scale_offset()
        low = (z * s[:, None, :]).amin(dim=1) + b  # (R, d) the lowest state of each restart
        need = (b - low + 0.5 * self.unit * s) / self.unit  # half a prior spread above zero
        raise_to = torch.where(self.positive & (low < 0.5 * self.unit * s), need, self.offset)
        self.offset.copy_(torch.maximum(self.offset, raise_to))

    @property
    def learned(self) -> bool:
        return bool(self.learn_scale.any() or self.learn_offset.any())

    def scale_offset(self, restarts: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(R, d) scale and offset (of the restarts indexed, if given); fixed entries are
        constants, not parameters."""
        log_scale, offset = self.log_scale, self.offset
        log_scale0, offset0 = self.log_scale0, self.offset0
        if restarts is not None:
            log_scale, offset = log_scale[restarts], offset[restarts]
            log_scale0, offset0 = log_scale0[restarts], offset0[restarts]
        s = torch.where(self.learn_scale, log_scale, log_scale0).exp()
        b = torch.where(self.learn_offset, offset, offset0) * self.unit
        return s, b

    def to_state(self, z: torch.Tensor, restarts: torch.Tensor | None = None) -> torch.Tensor:
        """z (R, ..., d) -> x = s*z + b; with `restarts`, z holds those restarts only."""
        s, b = self.scale_offset(restarts)
        shape = (s.shape[0],) + (1,) * (z.dim() - 2) + (s.shape[1],)
        return z * s.reshape(shape) + b.reshape(shape)

    def to_latent(self, x: torch.Tensor, restarts: torch.Tensor | None = None) -> torch.Tensor:
        s, b = self.scale_offset(restarts)
        shape = (s.shape[0],) + (1,) * (x.dim() - 2) + (s.shape[1],)
        return (x - b.reshape(shape)) / s.reshape(shape)

    def values(self, restart: int) -> dict[str, dict[str, float]]:
        s, b = self.scale_offset()
        return {st: {"scale": float(s[restart, i].detach()), "offset": float(b[restart, i].detach())}
                for i, st in enumerate(self.states)}
