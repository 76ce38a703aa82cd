"""The plan of a fit: every choice resolved once, with its reason, before any training.

A choice the user may leave to fitode ("auto": the observation model, the encoder, the training
window) is decided here and nowhere else. Everything after reads the plan: the trainer, the
header the command line prints, result.json and fit.json, so the three cannot disagree (they
did: a run once recorded its window as chosen in one file and as asked in the other).
"""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Mapping

import torch

from fitode.eqparse import OdeSystem, ParamSpec
from fitode.errors import TrainingError

from .config import ENCODER_NAMES, MIN_WINDOW, TrainConfig, resolve_encoder
from .window import resolve_window
from .observe import ObservationModel, resolve_observation
from .threads import torch_threads

CHOICES = ("observation", "encoder", "window")  # the choices a plan records, in the order they are printed


@dataclass(frozen=True)
class Choice:
    """One resolved choice: its value and why, in one line."""

    value: Any
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "reason": self.reason}


@dataclass(frozen=True)
class FitPlan:
    """A fit fully resolved: no "auto" and no None left where training needs a value.

    config: every training option, its window and encoder concrete. observation: the model
    instance that reads the frames. n_train of n_frames frames are trained on, dt apart. init:
    the user's starting values for restart 1 (None: the equation file's). choices: the value and
    reason of every choice fitode made or was told.
    """

    system: OdeSystem
    params: Mapping[str, ParamSpec]
    config: TrainConfig
    observation: ObservationModel
    dt: float
    n_frames: int
    n_train: int
    init: Mapping[str, float] | None
    choices: Mapping[str, Choice]

    def __post_init__(self) -> None:
        if self.config.window is None or self.config.encoder not in ENCODER_NAMES:
            raise ValueError("a FitPlan needs a concrete window and encoder (use make_plan)")
        if set(self.choices) != set(CHOICES):
            raise ValueError(f"a FitPlan records the choices {', '.join(CHOICES)}")

    @property
    def prior(self) -> tuple[float, float]:
        return self.config.prior

    def to_dict(self) -> dict[str, Any]:
        """The choices as result.json and fit.json record them: {name: {value, reason}}."""
        return {name: self.choices[name].to_dict() for name in CHOICES}

    def lines(self) -> list[str]:
        """The header's lines for what training will do and why."""
        c = self.config
        training = (f"{c.restarts} restart{'s' if c.restarts != 1 else ''}, up to {c.max_steps} steps, window "
                    f"{c.window} frames, {c.integrator} integrator, {c.device}, seed {c.seed}")
        if self.observation.applies("direct"):
            # a measured path is fitted by the equation's trajectory; the trainer runs only if that fails
            lines = [f"fit: the measured path directly, {c.restarts} starting point{'s' if c.restarts != 1 else ''} "
                     f"(if that fails, an encoder is trained: {training})"]
        else:
            lines = [f"training: {training}"]
        lines += [f"{name}: {self.choices[name].reason}" for name in ("window", "observation")]
        for part in getattr(self.observation, "parts", {"": self.observation}).values():
            if getattr(part, "light_reason", None):
                lines.append(f"light: {part.light_reason}")
        lines.append(f"encoder: {self.choices['encoder'].reason}")
        return lines


def _check_length(system: OdeSystem, config: TrainConfig, n_frames: int, n_train: int) -> None:
    """A clip too short for the equation, said in a user's words before any choice is made on it:
    a window needs the frames the initial state is read from (codegen.differences) and one to
    predict, and training one window and a frame past it."""
    from fitode.codegen.differences import init_scheme
    need = max(init_scheme(system.max_order, config.initial_state).context + 2, MIN_WINDOW + 1)
    if n_frames < need:
        raise TrainingError(f"the clip has {n_frames} frame{'s' if n_frames != 1 else ''}; this equation needs at "
                            f"least {need} (a longer clip, or a smaller --stride)")
    if n_train < need:
        raise TrainingError(f"the training part of the clip has {n_train} frames; this equation needs at least "
                            f"{need} (a larger --train-fraction)")


def make_plan(system: OdeSystem, params: Mapping[str, ParamSpec], frames: torch.Tensor, dt: float,
              config: TrainConfig, *, observe: str | ObservationModel | None = None, n_train: int | None = None,
              init: Mapping[str, float] | None = None, observe_source: str = "as asked", track=None, lengths=None) -> FitPlan:
    """Resolve every choice of a fit on its frames (T, C, H, W): the observation model (auto looks
    at the training frames), the encoder it reads with, and the training window.
    observe_source: where a named model came from ("as asked", "from the equation file").
    track: the reader's track of the frames (observe.track.Track), which the models that measure
    a place read; None: they measure the frames."""
    n_frames = int(frames.shape[0])
    n_train = n_frames if n_train is None else int(n_train)
    _check_length(system, config, n_frames, n_train)
    if track is not None and len(track) != n_frames:
        track = None  # frames cut or subsampled after reading: the track is not theirs
    with torch_threads(config.threads):
        observation = resolve_observation(observe, system, frames[:n_train], config.light, config.encoder,
                                          source=observe_source, track=track, n_train=n_train)
    if lengths is not None:  # how a measured length reads in px or metres (observe.base.Lengths)
        observation.use_lengths(lengths)
    config, encoder_reason = resolve_encoder(config, system, observation)
    config, window_reason = resolve_window(config, frames[:n_train], dt)
    if n_train < config.window + 1:
        raise TrainingError(f"{n_train} training frames are fewer than one window of {config.window} frames plus "
                            "one; use a longer clip, a smaller --stride or a smaller --window")
    choices = {"observation": Choice(observation.name, observation.reason),
               "encoder": Choice(config.encoder, encoder_reason),
               "window": Choice(config.window, window_reason)}
    return FitPlan(system=system, params=MappingProxyType(dict(params)), config=config, observation=observation,
                   dt=float(dt), n_frames=n_frames, n_train=n_train,
                   init=MappingProxyType(dict(init)) if init else None, choices=MappingProxyType(choices))

