"""Observation models: what the camera measures about the state, and the encoder that reads it.

One file per model behind a base class (base.py), the signal subspace (subspace.py), the
tracking of where something is (tracking.py) and how large it looks (extent.py), the camera's
transfer curve (light.py), the auto choice (auto.py), one model per state (per_state.py) and the
torch-free catalog of names the command line reads (catalog.py). The catalog is importable
without torch; every other name here loads its module (and torch) on first use.
"""
from __future__ import annotations

import importlib

from .catalog import AUTO, CHOICES, MODELS, auto_rule, format_observe, model_class, parse_observe

_WHERE = {
    "ObservationModel": "base", "MeasuredObservation": "base", "Prepared": "base", "CHECKS": "base",
    "BrightnessObservation": "brightness", "PositionObservation": "position", "AngleObservation": "angle",
    "fit_circle": "circle", "Circle": "circle", "Track": "track",
    "SizeObservation": "size", "DistanceObservation": "size", "LevelObservation": "level", "read_level": "level", "PerStateObservation": "per_state",
    "resolve_observation": "auto", "named_model": "auto", "look": "auto", "Look": "auto",
    "centroids": "tracking", "mend_one_way": "tracking", "mend_strays": "tracking", "mend": "tracking", "line_of_motion": "tracking", "one_way": "tracking",
    "noise_level": "tracking", "ONE_WAY": "tracking",
    "apparent_radii": "extent", "signal_subspace": "subspace", "SUBSPACE_JUMP": "subspace",
    "srgb_to_linear": "light", "linear_to_srgb": "light",
}

__all__ = ["AUTO", "CHOICES", "MODELS", "auto_rule", "format_observe", "model_class", "parse_observe", *_WHERE]


def __getattr__(name: str):
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)
