"""Starts from the data: constants that already fit what the frames do, whatever the user guessed.

The paper claims robustness to starts in [-10, 10], but from 3 of 7 such starts its trainer ends
in a wrong basin. Before the real restarts, a cheap search fits the equation to frozen latents
taken from the frames themselves (no encoder to learn): first the readout of the frames that
oscillates at the period with which the frames repeat, when they do (on real pendulums the
leading principal components also carry the swing's second harmonic, whose fit is the harmonic
trap at L/4), then the leading principal components. For each, the candidates (spread like the
restarts) are scored by how well their constants roll out the latent's windows, and the best
few are fitted by the trajectory fitter (fitode.train.trajectory: windows of the training
length, the equation's gauge learned as the trainer learns it); the best end is one start, in
that order, unless the equation follows that latent worse than MISFIT_MAX (a component of noise,
which some constant always "fits"). They become the starts of restarts 1, 2, ...; restart 0 keeps the user's (or the
equation file's) start.

Right constants are not enough: measured on the real pendulum clips, restarts that started at
the right L with a random encoder were dragged into the harmonic trap by the encoder. So a start
carries its frozen latent too, and the restart's encoder first learns to reproduce it
(fitode.train.loop.distill) before the joint training begins.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from fitode.eqparse import OdeSystem, ParamSpec
from fitode.eqparse.gauge import StateGauge

from .config import TrainConfig
from .trajectory import fit_trajectory, trajectory_misfit

COMPONENTS = 3  # principal components tried as the latent
CANDIDATES = 16  # starts scored on each
FITTED = 2  # the best scored candidates fitted on each
ITERATIONS = 200
MISFIT_MAX = 0.7  # a latent the equation follows worse than this (RMS, in its spreads) is no start: noise
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


def data_starts(components: np.ndarray, dt: float, system: OdeSystem, params: Mapping[str, ParamSpec],
                config: TrainConfig, plan: Mapping[str, StateGauge], candidates: list[dict[str, float]],
                n: int, period: float | None = None) -> list[DataStart]:
    """Up to n starts, one per frozen latent: the readout oscillating at `period` (the frames' own,
    if they repeat), then each leading principal component. candidates: the constants each
    search starts from (spread as the restarts are)."""
    if n <= 0 or system.dim != 1:
        return []  # one component is one state: a system of several states has no such shortcut
    options = {"integrator": config.integrator, "substeps": config.substeps, "windows": int(config.window),
               "gauge": plan if config.gauge else None}
    latents = [oscillation_readout(components, dt, period)] if period else []
    latents += [components[:, j] for j in range(min(COMPONENTS, components.shape[1]))]
    mean, std = config.prior
    starts: list[DataStart] = []
    for c in latents:
        if not np.std(c) > 0 or len(starts) == n:
            continue
        z = (mean + std * (c - c.mean()) / c.std())[:, None]
        scored = sorted((trajectory_misfit(system, params, z, dt, cand, **options), i)
                        for i, cand in enumerate(candidates))
        fits = [fit_trajectory(system, params, z, dt, candidates[i], iterations=ITERATIONS, **options)
                for score, i in scored[:FITTED] if math.isfinite(score)]
        fits = [f for f in fits if f is not None]
        if not fits:
            continue
        fitted = min(fits, key=lambda f: f.misfit)
        if fitted.misfit > MISFIT_MAX:  # a component of noise: any constant "fits" it (a decay at gamma 48)
            continue
        final = fitted.values
        if all(any(abs(final[k] - s.constants[k]) > DISTINCT * max(abs(s.constants[k]), 1e-9) for k in final)
               for s in starts):
            starts.append(DataStart(dict(final), c))
    return starts
