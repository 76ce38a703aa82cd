"""`fitode.fit`: the public API on arrays of frames."""
from __future__ import annotations

import math
from typing import Iterable, Mapping

import numpy as np
import torch

from fitode.eqparse import OdeSystem, ParamSpec
from fitode.errors import ConfigError, FitodeError
from fitode.train.config import TrainConfig
from fitode.train.observe import ObservationModel
from fitode.train.result import FitResult
from fitode.train.trainer import Callback, fit_frames


def fit(frames, dt: float, *, eq: str | None = None, system: str | OdeSystem | None = None,
        eq_file: str | None = None, const: Mapping[str, float] | None = None, free: Iterable[str] = (),
        init: Mapping[str, float] | None = None, params: Mapping[str, ParamSpec] | None = None,
        prior: tuple[float, float] | None = None, train_fraction: float = 1.0,
        observe: str | ObservationModel | None = None,
        callback: Callback | None = None, progress: bool = True, **options) -> FitResult:
    """Estimate the learnable constants of an equation from a frame sequence.

    frames: (T, H, W), (T, C, H, W) or (T, H, W, C) with C in {1, 3}, numpy or torch, any range.
    dt: seconds between consecutive frames.
    The equation is given as text (eq), a shipped system name or an OdeSystem (system), or an
    equation file (eq_file). const fixes constants, free frees known ones, init sets starting
    values for every restart, prior overrides the equation file's (mean, std). observe is the
    observation model: "auto" (None: chosen from the equation and the frames), "any", "brightness", or a
    fitode.train.observe.ObservationModel.
    options: any TrainConfig field (restarts, max_steps, window, integrator, substeps, encoder,
    use_kl, lr, const_lr, batch_windows, seed, device, threads, ...). Every bad option raises a
    fitode.ConfigError naming it, before any work.
    """
    ode, spec_params, spec_prior, spec_observe = _equation(eq, system, eq_file, const, free)
    if observe is None and spec_observe not in (None, "auto"):
        from fitode.train.observe import resolve_observation
        observe = resolve_observation(spec_observe, ode, light=options.get("light", "srgb"),
                                      source="from the equation file")
    if params is not None:
        spec_params = {**spec_params, **params}
    config = checked_config(ode, options, prior=prior, default_prior=spec_prior, init=init,
                            train_fraction=train_fraction, params=spec_params)
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating)) or not (dt > 0 and np.isfinite(dt)):
        raise ConfigError(f"dt must be a positive number of seconds, got {dt!r}")
    x = as_frames(frames)
    n_train = max(int(round(train_fraction * x.shape[0])), 1)
    return fit_frames(x, float(dt), ode, spec_params, config, train_frames=n_train,
                      init=init, callback=callback, progress=progress, observe=observe)


def checked_config(ode: OdeSystem, options: Mapping, *, prior=None, default_prior=(0.0, 1.0),
                   init: Mapping[str, float] | None = None, train_fraction: float = 1.0,
                   params: Mapping[str, ParamSpec] | None = None) -> TrainConfig:
    """Every check of a fit request that needs no frames, in one place (the API, the pipeline and
    batch all come through here): the training options, the prior, init's names, train_fraction."""
    if "prior" in options:
        raise ConfigError("give the prior as prior=(mean, std), not as a training option")
    config = TrainConfig.from_options(options, prior=tuple(prior) if prior is not None else tuple(default_prior))
    if not ode.learnable:
        raise FitodeError("the equation has no learnable constant to estimate (every name is fixed)")
    unknown = sorted(set(init or {}) - set(ode.learnable))
    if unknown:
        raise ConfigError(f"init names {', '.join(unknown)}, which is not a learnable constant "
                          f"(learnable: {', '.join(ode.learnable)})")
    for name, v in (init or {}).items():
        spec = params.get(name) if params else None
        lo, hi = (spec.min, spec.max) if spec is not None else (None, None)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or (lo is not None and not v > lo) or (hi is not None and not v < hi):
            raise ConfigError(f"init {name}={v!r} must be a number strictly inside its bounds "
                              f"({'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'})")
    if isinstance(train_fraction, bool) or not isinstance(train_fraction, (int, float)) or not 0 < train_fraction <= 1:
        raise ConfigError(f"train_fraction must be in (0, 1], got {train_fraction!r}")
    if config.device.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(f"device {config.device}: no CUDA device is available here (torch {torch.__version__}, "
                          f"built {'with' if torch.version.cuda else 'without'} CUDA); use cpu")
    return config


def as_frames(frames) -> torch.Tensor:
    """Any common frame layout -> float32 (T, C, H, W)."""
    x = torch.as_tensor(np.asarray(frames) if not isinstance(frames, torch.Tensor) else frames)
    x = x.detach().to(torch.float32)
    if x.ndim == 3:
        x = x[:, None]
    elif x.ndim == 4 and x.shape[-1] in (1, 3) and x.shape[1] not in (1, 3):
        x = x.permute(0, 3, 1, 2)
    if x.ndim != 4:
        raise FitodeError(f"frames must be (T, H, W) or (T, C, H, W), got shape {tuple(x.shape)}")
    if x.shape[0] < 2:
        raise FitodeError("need at least two frames")
    if not torch.isfinite(x).all():
        raise FitodeError("frames contain NaN or infinite values")
    return x.contiguous()


def _equation(eq, system, eq_file, const, free) -> tuple[OdeSystem, dict[str, ParamSpec], tuple[float, float],
                                                         str | None]:
    """The system, its parameters, prior and observation model (None: auto) from the equation given."""
    if isinstance(system, OdeSystem):
        if eq is not None or eq_file is not None:
            raise FitodeError("give the equation once: eq, system or eq_file")
        return system, {}, (0.0, 1.0), None
    from fitode.eqfile import resolve
    ode, spec = resolve(eq=eq, eq_file=eq_file, system=system, const=const, free=free)
    if spec is None:
        return ode, {}, (0.0, 1.0), None
    return ode, dict(spec.parameters), (spec.prior_mean, spec.prior_std), spec.observe
