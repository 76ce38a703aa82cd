"""Starts from the data: constants that already fit what the frames do, whatever the user guessed.

The paper claims robustness to starts in [-10, 10], but from 3 of 7 such starts its trainer ends
in a wrong basin. Before the real restarts, a cheap search fits the equation to frozen latents
taken from the frames themselves (no encoder to learn, so hundreds of steps cost little): first
the readout of the frames that oscillates at the period with which the frames repeat, when they
do (on real pendulums the leading principal components also carry the swing's second harmonic,
whose fit is the harmonic trap at L/4), then the leading principal components. For each, a
batch of candidates spread like the restarts is trained on the constants and the gauge alone,
and its best end is one start, in that order. They become the starts of restarts 1, 2, ...;
restart 0 keeps the user's (or the equation file's) start.

Right constants are not enough: measured on the real pendulum clips, restarts that started at
the right L with a random encoder were dragged into the harmonic trap by the encoder. So a start
carries its frozen latent too, and the restart's encoder first learns to reproduce it
(fitode.train.loop.distill) before the joint training begins.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
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
SEARCH_WINDOWS = 48  # windows a search step draws: a basin shows on a sample as on all, at a fraction of the cost
DISTINCT = 0.05  # two ends closer than this (relative, every constant) are one start


@dataclass
class DataStart:
    constants: dict[str, float]
    latent: np.ndarray  # (T,) the readout of the frames the restart's encoder starts from


def oscillation_readout(components: np.ndarray, dt: float, period: float) -> np.ndarray:
    """The linear readout of the components that oscillates most at `period`: the direction of
    the components' sin and cos projections (their leading singular vector)."""
    x = components - components.mean(axis=0)
    t = np.arange(len(x)) * dt
    m = np.stack([x.T @ np.sin(2 * np.pi * t / period), x.T @ np.cos(2 * np.pi * t / period)], axis=1)
    u, _, _ = np.linalg.svd(m, full_matrices=False)
    return x @ u[:, 0]


class _Frozen(nn.Module):
    """An 'encoder' without weights: restart r's latent is column columns[r] of its input (T, G, 1, 1)
    itself, so that the searches on G frozen latents train together as one batched model."""

    runs_some = True  # it can run a subset of its restarts (fitode.train.loop leaves stopped ones out)

    def __init__(self, columns: list[int]):
        super().__init__()
        self.restarts = len(columns)
        self.register_buffer("columns", torch.as_tensor(columns, dtype=torch.long), persistent=False)

    def forward(self, x: torch.Tensor, restarts: torch.Tensor | None = None) -> torch.Tensor:
        z = x.reshape(x.shape[0], -1)
        columns = self.columns if restarts is None else self.columns[restarts]
        return z[:, columns].T[..., None]


class _FrozenLatent(ObservationModel):
    name = "frozen"

    def __init__(self, columns: list[int]):
        super().__init__()
        self.columns = columns

    def encoder(self, architecture, in_shape, dim, seeds, output_mean=0.0, output_std=1.0):
        return _Frozen(self.columns)


def data_starts(components: np.ndarray, dt: float, system: OdeSystem, params: Mapping[str, ParamSpec],
                config: TrainConfig, plan: Mapping[str, StateGauge], candidates: list[dict[str, float]],
                n: int, period: float | None = None) -> list[DataStart]:
    """Up to n starts, one per frozen latent: the readout oscillating at `period` (the frames' own,
    if they repeat), then each leading principal component. candidates: the constants each
    search starts from (spread as the restarts are)."""
    if n <= 0 or system.dim != 1:
        return []  # one component is one state: a system of several states has no such shortcut
    latents = [oscillation_readout(components, dt, period)] if period else []
    latents += [components[:, j] for j in range(min(COMPONENTS, components.shape[1]))]
    latents = [c for c in latents if np.std(c) > 0]
    starts: list[DataStart] = []
    # the first n latents in one batch (a step costs little more for 32 restarts than for 16),
    # the others only where those gave fewer than n distinct starts
    for group in (latents[:n], latents[n:]):
        if group and len(starts) < n:
            _search(group, starts, n, dt, system, params, config, plan, candidates)
    return starts


def _search(latents: list[np.ndarray], starts: list[DataStart], n: int, dt: float, system: OdeSystem,
            params: Mapping[str, ParamSpec], config: TrainConfig, plan: Mapping[str, StateGauge],
            candidates: list[dict[str, float]]) -> None:
    """The candidates trained on every frozen latent together; each latent's best end is added
    to starts, in order, where it is new, until there are n."""
    mean, std = config.prior
    z = torch.as_tensor(np.stack([mean + std * (c - c.mean()) / c.std() for c in latents], axis=1),
                        dtype=torch.float32).reshape(-1, len(latents), 1, 1)
    k = len(candidates)
    # never more steps than the fit it seeds may take: a fit held to a few steps is asked to be quick
    steps = min(STEPS, config.max_steps)
    cfg = replace(config, restarts=k * len(latents), max_steps=steps, min_steps=min(config.min_steps, steps // 3),
                  horizon_warmup=min(config.horizon_warmup, steps // 3), batch_windows=SEARCH_WINDOWS)
    try:
        trained = train_restarts(z, dt, system, params, cfg, list(candidates) * len(latents),
                                 seeds=list(range(k)) * len(latents),
                                 observation=_FrozenLatent([g for g in range(len(latents)) for _ in range(k)]),
                                 plan=plan)
    except FitodeError:
        return
    for g, c in enumerate(latents):
        if len(starts) == n:
            return
        ends = [r for r in trained.records[g * k:(g + 1) * k] if r.status == "ok" and math.isfinite(r.loss) and r.final]
        if not ends:
            continue
        final = min(ends, key=lambda r: r.loss).final
        if all(any(abs(final[key] - s.constants[key]) > DISTINCT * max(abs(s.constants[key]), 1e-9) for key in final)
               for s in starts):
            starts.append(DataStart(dict(final), c))
