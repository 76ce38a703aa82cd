"""The verbs' shared flags (families of argparse arguments) and argparse types for their values.

Lists of names and NAME=VALUE items (`--const`, `--free`) are read by fitode.names, which equation
files use too."""
from __future__ import annotations

import argparse
import math
from collections.abc import Iterable


def positive_int(text: str) -> int:
    """argparse type for counts (--restarts, --max-steps, --window, --workers, ...): an integer >= 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {v}")
    return v


# --- flag families ---------------------------------------------------------------------------
# Every verb that takes an equation or training options gets its flags from here, so a flag is
# spelled, checked and documented the same way everywhere. Training choices and defaults come
# from fitode.train.config (torch-free), never from copied lists.

def add_equation_arguments(parser: argparse.ArgumentParser, *, title: str = "equation (exactly one)",
                           required: bool = True, eq_file: bool = True, const: bool = True,
                           free: bool = True, init: bool = False, many: bool = False,
                           const_help: str | None = None, candidates: bool = False):
    """--eq / --eq-file / --system (mutually exclusive), --const NAME=VALUE, --free NAME, --init NAME=VALUE.

    many: --const takes several values after one flag (`--const k=4 c=0.1`, as `fitode synth`
    always has); otherwise each flag takes one item (repeatable or comma-separated), which keeps
    `fitode --const g=9.81 VIDEO` from swallowing the video. Returns (group, exclusive) so a verb
    can add its own flags beside them (check's --list goes into the exclusive group).
    candidates: --eq is repeatable, each one a candidate equation (`fitode VIDEO --eq A --eq B`
    compares them: fitode.compare); args.eq is then a list.
    """
    group = parser.add_argument_group(title)
    ex = group.add_mutually_exclusive_group(required=required)
    if candidates:
        ex.add_argument("--eq", metavar="TEXT", action="append",
                        help="the equation, e.g. \"x'' = -g/L*sin(x) - z*x'\"; repeat it to compare candidate "
                             "equations on held-out stretches of the clip (docs/comparison.md)")
    else:
        ex.add_argument("--eq", metavar="TEXT", help="the equation, e.g. \"x'' = -g/L*sin(x) - z*x'\"")
    if eq_file:
        ex.add_argument("--eq-file", metavar="PATH", help="an equation file (TOML)")
    ex.add_argument("--system", metavar="NAME", help=f"a shipped equation file by name: {_systems()}")
    repeat = dict(nargs="+", action="extend") if many else dict(action="append")
    if const:
        group.add_argument("--const", metavar="NAME=VALUE", default=[], **repeat,
                           help=const_help or "fix a constant to a value (repeatable, or comma-separated)")
    if free:
        group.add_argument("--free", metavar="NAME", default=[], action="append",
                           help="learn a known constant such as g instead of fixing it (repeatable, or comma-separated)")
    if init:
        group.add_argument("--init", metavar="NAME=VALUE", default=[], action="append",
                           help="start every restart from this value of a constant (repeatable)")
    return group, ex


def _systems() -> str:
    try:
        from fitode.eqfile import list_systems
        return ", ".join(list_systems())
    except Exception:  # noqa: BLE001 - help text must never break the command
        return "see fitode/equations/"


# flag help, by TrainConfig field; the default is appended from fitode.train.config.defaults()
_TRAINING_HELP = {
    "restarts": ("N", "independent restarts, trained together as one batched model"),
    "max_steps": ("N", "step limit per restart"),
    "min_steps": ("N", "steps before early stopping may stop a restart"),
    "window": ("N", "frames per training window"),
    "integrator": (None, "ODE integrator"),
    "encoder": (None, "frame encoder: auto (linear for a single first-order linear equation, else mlp), "
                      "mlp (the paper's), cnn, or linear (an affine map of the frames: for decays, see README)"),
    "light": (None, "how the brightness observation reads pixel values: auto (the default: whichever curve makes "
                    "the change one pattern), srgb (decoded to linear light, as phone video stores them) or linear "
                    "(already proportional to light)"),
    "device": (None, "where to train"),
    "seed": ("N", "random seed"),
    "threads": ("N", "torch threads for the fit"),
    "pieces": (None, "auto: fit every stretch where one trajectory holds (between a release, bounces, a stop), "
                     "the constants shared; one: only the longest stretch"),
}
TRAINING_FLAGS = ("restarts", "max_steps", "min_steps", "window", "integrator", "encoder", "light", "device", "seed",
                  "threads", "pieces")


def add_training_arguments(parser: argparse.ArgumentParser, *, title: str = "training",
                           fields: Iterable[str] = TRAINING_FLAGS):
    """One flag per TrainConfig field in `fields` (--max-steps for max_steps), default None (unset).

    Each value is checked at parse time by TrainConfig's own rules, so `--window 2` is a one-line
    argparse error naming --window rather than a failure after the video is decoded.
    """
    from fitode.train import config as cfg

    names = {"integrator": cfg.INTEGRATOR_NAMES, "encoder": cfg.ENCODER_CHOICES, "device": cfg.DEVICE_NAMES,
             "light": cfg.LIGHT_CHOICES, "pieces": cfg.PIECES_CHOICES}
    defaults = cfg.defaults()
    group = parser.add_argument_group(title)
    for name in fields:
        metavar, text = _TRAINING_HELP[name]
        default = defaults[name]
        unset = {"window": "auto: at least 20, and long enough to span the dynamics' time constant"}
        shown = (unset.get(name, "torch's choice") if default is None
                 else (f"{default:g}" if isinstance(default, float) else default))
        kwargs = dict(help=f"{text} (default {shown})", default=None)
        if name in names:
            kwargs["choices"] = names[name]
        else:
            kwargs.update(type=_config_value(name), metavar=metavar)
        group.add_argument("--" + name.replace("_", "-"), **kwargs)
    return group


def _config_value(name: str):
    """argparse type for one TrainConfig field: convert, then let TrainConfig judge the value."""
    def convert(text: str):
        from fitode.errors import ConfigError
        from fitode.train.config import TrainConfig

        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        try:
            TrainConfig(**{name: value})
        except ConfigError as exc:
            message = str(exc)
            # "window must be at least 3 frames" -> "must be ..." after argparse's "argument --window:"
            if message.startswith(name + " "):
                message = message[len(name) + 1:]
            raise argparse.ArgumentTypeError(message) from None
        return value
    convert.__name__ = name  # argparse names the type in some messages
    return convert


def training_options(args: argparse.Namespace, fields: Iterable[str] = TRAINING_FLAGS) -> dict:
    """The training flags the user gave, as TrainConfig keyword arguments (unset ones left out)."""
    return {name: getattr(args, name) for name in fields if getattr(args, name, None) is not None}


def prior_value(text: str) -> tuple[float, float]:
    """argparse type for --prior MEAN,STD: two finite numbers, STD > 0."""
    parts = [s.strip() for s in text.split(",")]
    try:
        if len(parts) != 2:
            raise ValueError
        mean, std = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expects MEAN,STD such as 1,0.2; got {text!r}") from None
    if not (math.isfinite(mean) and math.isfinite(std) and std > 0):
        raise argparse.ArgumentTypeError(f"{text}: STD must be a positive number and both must be finite")
    return mean, std


def fraction(text: str) -> float:
    """argparse type for a fraction in (0, 1] (--train-fraction)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < v <= 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1], got {text}")
    return v
