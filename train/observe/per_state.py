"""One observation per state: each state's own measured model, its single column in the
equation's state order (`observe = {x = "position", y = "size"}`, --observe "x=position;y=size")."""
from __future__ import annotations

from typing import Mapping, Sequence

import torch

from fitode.errors import ConfigError

from .base import MeasuredObservation, ObservationModel, Prepared
from .catalog import check_states, format_observe


class PerStateObservation(MeasuredObservation):
    """The states measured each by a model of its own. Only measured models combine: a free
    encoder's latent is learned from the whole frame, not measured for one state."""

    def __init__(self, parts: Mapping[str, ObservationModel], states: Sequence[str]):
        super().__init__()
        check_states(dict(parts), list(states))
        self.name = format_observe({s: parts[s].name + (f"@{parts[s].object}" if parts[s].object else "")
                                    for s in states})
        free = [f"{s}={parts[s].name}" for s in states if not parts[s].measured]
        if free:
            raise ConfigError(f"observe {self.name}: {', '.join(free)} reads a free latent from the whole frame, which "
                              "cannot be one state's column; give a measured model (position, size, distance) per "
                              "state, or one model for every state")
        units = {parts[s].physical_units for s in states}
        if len(units) > 1:
            raise ConfigError(f"observe {self.name}: some states are measured in physical units and some in the "
                              "latent's own; give models that read alike")
        self.parts = {s: parts[s] for s in states}  # in the equation's order
        self.physical_units = units.pop()

    def bind(self, system) -> None:
        super().bind(system)
        for state, model in self.parts.items():
            model.bind(system)
            model.equation_states = (state,)  # each part measures its own state (a position named y reads y)

    def use_track(self, track) -> None:
        super().use_track(track)
        for model in self.parts.values():
            model.use_track(track)

    def use_lengths(self, lengths) -> None:
        super().use_lengths(lengths)
        for model in self.parts.values():
            model.use_lengths(lengths)

    def applies(self, check: str) -> bool:
        # the perspective re-reading bends a one-dimensional path
        return False if check == "perspective" else super().applies(check)

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        columns, notes, cautions, components, drawings, mended = [], [], [], None, [], set()
        units, unit_scale, hints = [], [], []
        for state, model in self.parts.items():
            one = model.prepare(frames, architecture, fit_frames)
            if tuple(one.inputs.shape[1:]) != (1, 1, 1):
                raise ConfigError(f"observe {state}={model.name}: the model gives inputs of shape "
                                  f"{tuple(one.inputs.shape)}; one state's model measures one column")
            columns.append(one.inputs.reshape(-1))
            notes.append(f"{state}: {one.note}")
            if one.caution:
                cautions.append(f"{state}: {one.caution}")
            if one.hint:
                hints.append(one.hint)
            mended.update(one.mended)
            components = one.components if components is None else components
            drawings.append((state, one.drawing))
            units.append(one.units[0] if one.units else None)
            unit_scale.append(one.unit_scale[0] if one.unit_scale else None)
        given = all(u is not None for u in units)  # a unit for every state, or the path has none
        inputs = torch.stack(columns, dim=1).reshape(len(columns[0]), len(columns), 1, 1)
        return Prepared(inputs, components, len(columns), "; ".join(notes), "; ".join(cautions) or None,
                        tuple(self.parts), _merged(self.name, drawings), mended=tuple(sorted(mended)),
                        units=tuple(units) if given else None, unit_scale=tuple(unit_scale) if given else None,
                        hint="; ".join(hints) or None)

    def describe(self) -> str:
        return "; ".join(f"{s}: {m.describe()}" for s, m in self.parts.items())


def _merged(name: str, drawings: list) -> dict | None:
    """One drawing of every state's (state, drawing): each key from the first state's model that
    has it (two states that read one object, x=position;y=size, share its track), and what each
    state read (a part's model names only the equation's first state: it measures one column)."""
    parts = [(s, d) for s, d in drawings if d]
    if not parts:
        return None
    out: dict = {"kind": name}
    for _, d in parts:
        for key, value in d.items():
            out.setdefault(key, value)
    out["kind"] = name
    out["states"] = {s: next(iter(d.get("states", {}).values()), d["kind"]) for s, d in parts}
    return out
