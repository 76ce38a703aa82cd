"""The measurement stage: what the plan's observation reads off the frames, before any fit.

read -> plan -> measure -> fit -> assess -> report: `measure` runs the observation once, so that
what cannot be measured (an angle where nothing swings, a level where no water line shows) fails
here, in one line, before the command line prints its header or makes an output folder; the fit
then takes the Measurement instead of measuring again.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .observe.base import Lengths, Prepared
from .plan import FitPlan
from .threads import torch_threads


@dataclass
class Measurement:
    """What was measured of a clip's frames, for the fit that follows.

    time: the frames' times in seconds from the first frame used (T,), plan.dt apart.
    states: the equation's states in order. units: each measured state's unit (px, or m with a
    scale stick; radians for an angle), None for a free encoder's latent. columns: the measured
    path (T, k) in those units, y up (None for a free encoder). lengths: how a length on the
    frames reads (source pixels per frame pixel, the scale applied). note: the observation's
    one-line account of what it read and why. prepared: what the encoder or the direct fit reads
    (observe.base.Prepared), kept for the fit.
    """

    time: np.ndarray
    states: tuple[str, ...]
    units: dict[str, str] | None
    columns: np.ndarray | None
    lengths: Lengths
    note: str
    prepared: Prepared


def measure(frames: torch.Tensor, plan: FitPlan) -> Measurement:
    """The plan's observation run on the frames (T, C, H, W): a Measurement, or the observation's
    ConfigError (one line) where the frames cannot be measured so."""
    system, observation = plan.system, plan.observation
    device = torch.device(plan.config.device)
    with torch_threads(plan.config.threads):
        prepared = observation.prepare(frames.to(device), plan.config.encoder,
                                       fit_frames=plan.n_train).in_order(system.states)
    units, columns = None, None
    measured = prepared.states is not None and prepared.inputs.dim() == 4 and tuple(prepared.inputs.shape[2:]) == (1, 1)
    if measured:
        raw = prepared.inputs.reshape(prepared.inputs.shape[0], -1).double().cpu().numpy()
        if observation.physical_units:
            units, columns = {s: "rad" for s in prepared.states}, raw
        elif prepared.unit_scale is not None:
            units = dict(zip(prepared.states, prepared.units))
            columns = raw * np.asarray(prepared.unit_scale, dtype=float)
    return Measurement(np.arange(frames.shape[0]) * plan.dt, tuple(system.states), units, columns,
                       observation.lengths, prepared.note, prepared)
