"""Starts from the data: constants that already fit what the frames do, whatever the user guessed.

The paper claims robustness to starts in [-10, 10], but from 3 of 7 such starts its trainer ends
in a wrong basin. Before the real restarts, a cheap search fits the equation to the frames'
own leading principal components, taken as a frozen latent (no encoder to learn, so hundreds of
steps cost little): for each of the first few components, a batch of candidates spread like the
restarts is trained on the constants and the gauge alone. The best distinct ends become the
starts of restarts 1, 2, ...; restart 0 keeps the user's (or the equation file's) start.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Mapping

import numpy as np
import torch
from torch import nn

from fitode.eqparse import OdeSystem, ParamSpec
from fitode.eqparse.gauge import StateGauge
from fitode.errors import FitodeError

from .config import TrainConfig
from .loop import train_restarts
from .observe import ObservationModel

COMPONENTS = 3  # principal components tried as the latent
CANDIDATES = 16  # starts trained on each
STEPS = 300
DISTINCT = 0.05  # two ends closer than this (relative, every constant) are one start


class _Frozen(nn.Module):
    """An 'encoder' without weights: the latent is the input itself, for every restart."""

    def __init__(self, restarts: int):
        super().__init__()
        self.restarts = restarts

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = x.reshape(x.shape[0], -1)
        return z[None].expand(self.restarts, *z.shape)


class _FrozenLatent(ObservationModel):
    name = "frozen"

    def encoder(self, architecture, in_shape, dim, seeds, output_mean=0.0):
        return _Frozen(len(seeds))


def data_starts(components: np.ndarray, dt: float, system: OdeSystem, params: Mapping[str, ParamSpec],
                config: TrainConfig, plan: Mapping[str, StateGauge], candidates: list[dict[str, float]],
                n: int) -> list[dict[str, float]]:
    """Up to n starts found by fitting the equation to each leading component as a frozen latent.
    candidates: the constants each search starts from (spread as the restarts are)."""
    if n <= 0 or system.dim != 1 or components.shape[1] == 0:
        return []  # one component is one state: a system of several states has no such shortcut
    cfg = replace(config, restarts=len(candidates), max_steps=STEPS, min_steps=min(config.min_steps, STEPS // 3),
                  horizon_warmup=min(config.horizon_warmup, STEPS // 3), batch_windows=None)
    mean, std = config.prior
    ends: list[tuple[float, dict[str, float]]] = []
    for j in range(min(COMPONENTS, components.shape[1])):
        c = components[:, j]
        if not np.std(c) > 0:
            continue
        z = torch.as_tensor(mean + std * (c - c.mean()) / c.std(), dtype=torch.float32).reshape(-1, 1, 1, 1)
        try:
            trained = train_restarts(z, dt, system, params, cfg, candidates, seeds=list(range(len(candidates))),
                                     observation=_FrozenLatent(), plan=plan)
        except FitodeError:
            continue
        for rec in trained.records:
            if rec.status == "ok" and math.isfinite(rec.loss) and rec.final:
                ends.append((rec.loss, dict(rec.final)))
    ends.sort(key=lambda e: e[0])
    starts: list[dict[str, float]] = []
    for _, final in ends:
        if all(any(abs(final[k] - s[k]) > DISTINCT * max(abs(s[k]), 1e-9) for k in final) for s in starts):
            starts.append(final)
        if len(starts) == n:
            break
    return starts
