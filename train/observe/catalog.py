"""The observation models by name: one table, torch-free, that the command line, equation files,
`fitode check` and the training configuration all read (nothing else lists the names).

Each entry names the file of this package that holds the model's class, the class, a short label
(what the camera measures) and one line on what the latent is and which bends of it the reading
removes. Adding a model is its file and one entry here. An observation is named as one model for
every state ("position") or one per state ("x=position;y=size" on the command line, a table
`observe = {x = "position", y = "size"}` in an equation file); only models whose latent is a
measured coordinate can be combined so (fitode.train.observe.per_state).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Mapping

from fitode.errors import ConfigError


@dataclass(frozen=True)
class Entry:
    module: str  # the file of fitode.train.observe that holds the class
    cls: str
    label: str  # what the camera measures, a few words
    line: str  # what the latent is and which bends of it the reading removes


MODELS: dict[str, Entry] = {
    "any": Entry("base", "ObservationModel", "a free encoder, the paper's",
                 "a free encoder: the latent may be any function of the pixels; the gauge fixes only its scale and "
                 "offset"),
    "brightness": Entry("brightness", "BrightnessObservation", "linear in the light, decoded from sRGB; see --light",
                        "the pixels are decoded from sRGB to linear light and read linearly: no bend of the latent "
                        "(I -> I**p, which would multiply a decay rate by p) and no transfer curve (about p = 1/2.2)"),
    "position": Entry("position", "PositionObservation", "where the change is, along its line of motion",
                      "the centroid of the change along its line of motion, read linearly: no bend of the latent "
                      "(a bent parabola is nearly another parabola, with another g), but for the one bend a camera "
                      "at an angle makes (a perspective), which the whole clip fixes after a first training"),
    "angle": Entry("angle", "AngleObservation", "the angle of a swing about its fitted pivot",
                   "the angle in radians about the pivot of a circle fitted robustly to the tracked path, from the "
                   "direction it hangs in: the state in its own units, with no gauge to learn (a position would read "
                   "L sin(theta))"),
    "level": Entry("level", "LevelObservation", "the height of a water line that rises or falls",
                   "the height of a horizontal edge (a water line) that moves up or down, from the shift of the "
                   "rows' profile across the tank, read linearly: no bend of the latent, and nothing floating on "
                   "the water mixed in"),
    "size": Entry("size", "SizeObservation", "the apparent radius of what grows or shrinks",
                  "the apparent radius of what grows or shrinks, read linearly: no bend of the latent"),
    "distance": Entry("size", "DistanceObservation", "its reciprocal: motion along the line of sight",
                      "the reciprocal of the apparent radius of what moves along the line of sight (a pinhole camera "
                      "sees radius f R / d), read linearly: the latent is affine in the distance, unbent"),
}
AUTO = "auto"
CHOICES = (AUTO,) + tuple(MODELS)
AUTO_LABEL = "chosen from the equation and a look at the frames, and printed"


def auto_rule(power_symmetric: bool) -> list[str]:
    """The rule behind "auto" (fitode.train.observe.auto.resolve_observation), in prose, for an
    equation that is (or is not) a single first-order linear equation, whose rate a bend of the
    latent would change."""
    level = ("auto -> level for a single first-order state named along the vertical (h, y, z) where the frames "
             "show a horizontal edge that moves one way: " + MODELS["level"].line)
    moving = ("auto -> position where the change moves one way (a fall, a slide, a level), where it moves and "
              "every state's name says its image axis (x across; y, h, z up), or where a single state whose scale "
              "and zero the equation leaves free (s'' = -a) moves back and forth along a straight line (read along "
              "it, positive the way it first moves, or the other way where the equation's constants then come out "
              "positive): " + MODELS["position"].line)
    swing = ("auto -> angle, before the names, where a single state's path goes back and forth along an arc that "
             "clearly bends about a centre (a pendulum, whatever its state is named; a path that runs one way, as a "
             "throw between its launch and its landing, is no swing): " + MODELS["angle"].line)
    if not power_symmetric:
        return [level, swing, moving, "elsewhere any, as no constant follows a bend of the latent: " + MODELS["any"].line]
    return [level, swing, moving, "brightness where the change stays in place (it brightens or dims): " + MODELS["brightness"].line,
            "where it moves back and forth: any, with the linear encoder, which removes the bend only"]


def help_text() -> str:
    """The --observe help of the command line."""
    models = ", ".join(f"{name} ({e.label})" for name, e in MODELS.items())
    return (f"what the camera measures about the state: {models}, or {AUTO} ({AUTO_LABEL}); one per state as "
            "\"x=position;y=size\" (default: the equation file's, else auto)")


def model_class(name: str) -> type:
    """The class a catalog name stands for (imports its module, and torch, on first use)."""
    entry = MODELS.get(name)
    if entry is None:
        raise ConfigError(f"unknown observation model {name!r}; choose one of {', '.join(CHOICES)}")
    return getattr(importlib.import_module(f"{__package__}.{entry.module}"), entry.cls)


def parse_observe(value: str | Mapping[str, str] | None) -> str | dict[str, str] | None:
    """A model's name (one for every state), or {state: name} from "x=position;y=size" or a
    mapping; None stays None. A name outside the catalog is a ConfigError."""
    if value is None:
        return None
    if isinstance(value, str) and "=" not in value:
        name = value.strip()
        if split_object(name)[0] not in CHOICES:
            raise ConfigError(f"unknown observation model {name!r}; choose one of {', '.join(CHOICES)}")
        return name
    if isinstance(value, str):
        pairs = [part.split("=", 1) for part in value.replace(",", ";").split(";") if part.strip()]
        if any(len(p) != 2 for p in pairs):
            raise ConfigError(f"observe {value!r}: give one model per state as \"x=position;y=size\"")
        value = {state.strip(): name.strip() for state, name in pairs}
    if not isinstance(value, Mapping) or not value or not all(isinstance(v, str) for v in value.values()):
        raise ConfigError(f"observe must be a model's name or one per state (x=position;y=size), got {value!r}")
    for state, name in value.items():
        base, _ = split_object(name)
        if base not in MODELS:
            raise ConfigError(f"observe {state}={name!r}: choose one of {', '.join(MODELS)} for a state")
    return dict(value)


def split_object(name: str) -> tuple[str, int | None]:
    """"position@2" -> ("position", 2): the model, and the moving object it reads (the k-th from
    the left that the tracker follows; None: the strongest)."""
    base, at, k = name.partition("@")
    if not at:
        return name, None
    if not k.strip().isdigit() or int(k) < 1:
        raise ConfigError(f"observe {name!r}: name the object as MODEL@K, K = 1, 2, ... from the left (position@2)")
    return base.strip(), int(k)


def format_observe(spec: str | Mapping[str, str] | None) -> str | None:
    """The observation as the command line names it: "position", or "x=position;y=size"."""
    if spec is None or isinstance(spec, str):
        return spec
    return ";".join(f"{state}={name}" for state, name in spec.items())


def check_states(spec: str | Mapping[str, str] | None, states) -> None:
    """A per-state observation names every state of the equation once, and nothing else."""
    if spec is None or isinstance(spec, str):
        return
    unknown = [s for s in spec if s not in states]
    if unknown:
        raise ConfigError(f"observe names {', '.join(unknown)}, which is not a state of the equation "
                          f"(states: {', '.join(states)})")
    missing = [s for s in states if s not in spec]
    if missing:
        raise ConfigError(f"observe names no model for {', '.join(missing)}: give one for every state "
                          f"({';'.join(f'{s}=...' for s in states)})")
