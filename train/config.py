"""The training configuration, checked once, here, for every entry point (API, pipeline, batch).

torch-free on purpose: the command line builds its flags and checks options from this module
without paying for a torch import. The names of encoders, integrators and initial-state schemes
are listed here and nowhere else; the modules that implement them assert they agree.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, Mapping

from fitode.errors import ConfigError

from .observe.catalog import CHOICES

MIN_WINDOW = 3  # the fewest frames a training window has

ENCODER_NAMES = ("mlp", "cnn", "linear")
ENCODER_CHOICES = ("auto",) + ENCODER_NAMES  # auto: linear where a free encoder could report any rate
# what the camera measures about the state: the catalog of train/observe (torch-free); auto: chosen from the
# equation and the frames
OBSERVE_CHOICES = CHOICES
# how the brightness observation reads pixel values (train/observe/light.py); auto: the curve that makes the change one pattern
LIGHT_CHOICES = ("auto", "srgb", "linear")
INTEGRATOR_NAMES = ("rk4", "symplectic", "euler")
INTEGRATOR_ALIASES = {"paper": "symplectic", "semi-implicit": "symplectic", "semi_implicit": "symplectic",
                      "explicit-euler": "euler"}
INITIAL_STATE_NAMES = ("difference", "backward", "learnable")
DEVICE_NAMES = ("cpu", "cuda")


@dataclass
class TrainConfig:
    """Every training option. Invalid values raise ConfigError (a FitodeError) naming the option.

    window: frames per training window (None: chosen from the frames, train/window.py). max_steps: step limit per restart. min_steps: no stop
    before this step. lr: the encoder's Adam learning rate. const_lr: base learning rate of the
    constants (scaled per constant, see fitode.codegen.constants). batch_windows: windows per
    step (None: all). use_kl: the KL term (off only for the paper's ablation). prior: (mean, std)
    of the latent. integrator, substeps, initial_state: how the physics block rolls out (see
    fitode.codegen). encoder: the frame encoder's architecture; "auto" picks linear for a single
    first-order linear equation (a free encoder could report any power of its state, which
    decays at any rate) and mlp (the paper's) otherwise, or what the observation model reads
    with. light: how the brightness observation reads pixel values, "srgb" (decoded to linear
    light, as phone video stores them), "linear" (already proportional to light) or "auto" (whichever
    makes the change one pattern; sRGB, with a caution on the verdict, where the frames cannot tell). gauge: learn the scale and
    offset between latent and physical state where the equation needs them (off: the paper's
    latent = state). tol, patience, settle_factor: the stopping rule (train/stopping.py).
    horizon_warmup: steps over which the rollout grows to the whole window. selection_factor:
    runs whose loss is within this factor of the best are candidates for the estimate.
    restarts: independent restarts, trained together as one batched model. seed: all randomness.
    device: cpu or cuda. threads: torch intra-op threads for the fit (None: torch's default; 1 by
    default, because these small models gain little from threads and lose much when the machine
    is busy: 2 threads were 11x slower than 1 under load).
    check_every: steps between checks that the loss and constants are finite (each check is a
    host synchronisation). stretch: on a measured path, fit only the stretch that one trajectory
    of the equation explains (train/stretch.py); off where the user chose the frames (--start/--end).
    """

    window: int | None = None
    max_steps: int = 2000
    min_steps: int = 200
    lr: float = 1e-4
    const_lr: float = 0.05
    batch_windows: int | None = None
    use_kl: bool = True
    prior: tuple[float, float] = (0.0, 1.0)
    integrator: str = "rk4"
    substeps: int = 1
    initial_state: str = "difference"
    encoder: str = "auto"
    light: str = "auto"
    gauge: bool = True
    tol: float = 1e-3
    patience: int = 50
    horizon_warmup: int = 200
    settle_factor: float = 0.1
    selection_factor: float = 1.5
    restarts: int = 4
    seed: int = 0
    device: str = "cpu"
    threads: int | None = 1
    check_every: int = 10
    stretch: bool = True

    def __post_init__(self) -> None:
        for name in ("max_steps", "restarts", "substeps", "patience", "check_every"):
            _positive_int(name, getattr(self, name))
        for name in ("min_steps", "horizon_warmup", "seed"):
            _int_at_least(name, getattr(self, name), 0)
        if self.window is not None:
            _positive_int("window", self.window)
        if self.window is not None and self.window < MIN_WINDOW:
            raise ConfigError(f"window must be at least {MIN_WINDOW} frames, got {self.window}")
        if self.batch_windows is not None:
            _positive_int("batch_windows", self.batch_windows)
        if self.threads is not None:
            _positive_int("threads", self.threads)
        for name in ("lr", "const_lr", "tol", "settle_factor"):
            _positive_float(name, getattr(self, name))
        _positive_float("selection_factor", self.selection_factor)
        if self.selection_factor < 1:
            raise ConfigError(f"selection_factor must be at least 1, got {self.selection_factor}")
        for name in ("use_kl", "gauge", "stretch"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be True or False, got {getattr(self, name)!r}")
        self.prior = _prior(self.prior)
        self.integrator = _choice("integrator", INTEGRATOR_ALIASES.get(self.integrator, self.integrator),
                                  INTEGRATOR_NAMES)
        self.initial_state = _choice("initial_state", self.initial_state, INITIAL_STATE_NAMES)
        self.encoder = _choice("encoder", self.encoder, ENCODER_CHOICES)
        self.light = _choice("light", self.light, LIGHT_CHOICES)
        device = str(self.device)
        if device.split(":")[0] not in DEVICE_NAMES:
            raise ConfigError(f"unknown device {self.device!r}; use cpu or cuda")
        self.device = device

    @classmethod
    def from_options(cls, options: Mapping[str, Any], **fixed: Any) -> "TrainConfig":
        """A config from user options: unknown names are one ConfigError listing the known ones."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ConfigError(f"unknown training option(s): {', '.join(unknown)} "
                              f"(known: {', '.join(sorted(known))})")
        return cls(**{**options, **fixed})

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["prior"] = list(self.prior)
        return d


def resolve_encoder(config: "TrainConfig", system, observation=None) -> tuple["TrainConfig", str]:
    """The architecture "auto" stands for with this equation and observation model, and why (one line)."""
    needed = getattr(observation, "architecture", None)
    if needed is not None:
        if config.encoder not in ("auto", needed):
            raise ConfigError(f"the {observation.name} observation reads the pixels with the {needed} encoder; "
                              f"encoder {config.encoder!r} does not apply (observe 'any' for a free encoder)")
        return replace(config, encoder=needed), f"{needed} (the {observation.name} observation reads the pixels linearly)"
    if config.encoder != "auto":
        return config, f"{config.encoder} (as asked)"
    from fitode.eqparse.identify import power_symmetric  # sympy: only when a fit is set up
    if power_symmetric(system):
        return replace(config, encoder="linear"), ("linear (auto: a single first-order linear equation, whose "
                                                   "rate a free encoder could multiply by any power)")
    return replace(config, encoder="mlp"), "mlp (auto: the paper's encoder)"


def defaults() -> dict[str, Any]:
    """The default value of every option (for help texts and reports)."""
    return TrainConfig().as_dict()


def _positive_int(name: str, v: Any) -> None:
    _int_at_least(name, v, 1)


def _int_at_least(name: str, v: Any, lo: int) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        what = "a positive integer" if lo == 1 else f"an integer >= {lo}"
        raise ConfigError(f"{name} must be {what}, got {v!r}")


def _positive_float(name: str, v: Any) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise ConfigError(f"{name} must be a positive number, got {v!r}")


def _prior(p: Any) -> tuple[float, float]:
    try:
        mean, std = (float(v) for v in p)
    except (TypeError, ValueError):
        raise ConfigError(f"prior must be (mean, std), got {p!r}") from None
    if not (math.isfinite(mean) and math.isfinite(std) and std > 0):
        raise ConfigError(f"prior must be (mean, std) with a finite mean and std > 0, got {p!r}")
    return mean, std


def _choice(name: str, v: Any, names: tuple[str, ...]) -> str:
    if v not in names:
        raise ConfigError(f"unknown {name} {v!r}; choose one of {', '.join(names)}")
    return v
