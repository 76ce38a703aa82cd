"""Observation models: what the camera measures about the state, and the encoder that reads it.

An observation model owns the whole path from raw frames to latent: `prepare` turns the frames
into what the encoder reads (once per fit), `encoder` builds the (batched) encoder for R
restarts, and `regulariser` may add a term to the loss. What its latent means is the model's to
say, never a flag read elsewhere: `measured` (a measured coordinate read linearly),
`physical_units` (the state itself, in its own units: radians, metres), `applies(check)` (which
of the checks that depend on the model apply to it), `fixes_scale()`, `gauge_plan(plan)` and
`describe()`.

ObservationModel is the paper's: a free encoder ("any": mlp, cnn or linear) on the mean-removed
frames, restricted to their signal subspace (subspace.py). MeasuredObservation is the base of the
models that measure the state (a position, a size, a user's tracker): one input column per state
it measures, named in Prepared.states, read by a linear encoder that starts as the identity (in
physical units: that is the identity, and learns nothing). fitode.fit accepts a catalog name or an
instance, as PySINDy's estimator accepts its parts.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

import numpy as np
import torch

from fitode.errors import ConfigError

from ..encoders import BatchedEncoder, FixedReadout
from .catalog import MODELS
from .subspace import signal_subspace

# the checks whose use depends on what the latent is (ObservationModel.applies)
CHECKS = ("score", "quiet", "perspective", "trajectory", "rivals", "direct", "periods", "stretch")


@dataclass(frozen=True)
class Lengths:
    """How a length measured on the frames reads in the user's units: the source pixels per frame
    pixel along x and y (the reader's crop and shrink), and the metres per source pixel where a
    scale stick was given (fitode.scale), with its relative standard deviation."""

    frame_scale: tuple[float, float] = (1.0, 1.0)
    metres_per_px: float | None = None
    relative_std: float = 0.0

    @property
    def unit(self) -> str:
        return "m" if self.metres_per_px else "px"

    def factor(self, direction=(1.0, 0.0), source: bool = False) -> float:
        """The unit's amount in one pixel along direction (dx, dy) of the frames (source: a length
        measured in source pixels already, the reader's track)."""
        sx, sy = (1.0, 1.0) if source else self.frame_scale
        dx, dy = float(direction[0]), float(direction[1])
        norm = (dx * dx + dy * dy) ** 0.5 or 1.0
        px = ((dx * sx) ** 2 + (dy * sy) ** 2) ** 0.5 / norm
        return px * (self.metres_per_px or 1.0)


@dataclass
class Prepared:
    """The frames as the encoder reads them, and what the checks need from the same analysis."""

    inputs: torch.Tensor  # (T, C, H, W), or (T, k, 1, 1): k subspace coefficients or k measured columns
    components: np.ndarray  # (T, SCORE_COMPONENTS) leading principal-component coefficients
    rank: int
    note: str  # one line: the subspace kept and why
    caution: str | None = None  # a reason the measurement may be off (an object too small), for the verdict
    states: tuple[str, ...] | None = None  # the state each input column measures; None: a latent the encoder learns
    # what was measured, to draw on the frames (drawing.py's record; FitResult.meta["measurement"])
    drawing: dict[str, Any] | None = None
    # the reading a measured state did not take, where another is as plausible (a 2-D path read
    # along its line of motion: the reading across it), (T,) in the taken column's units, and
    # what it is ("across the line of motion"); the trainer fits it too and compares
    other: tuple[torch.Tensor, str] | None = None
    # the frames whose reading left the path of their neighbours and was read from them
    # (tracking.mend): the trainer weighs them on the frames it fits (tracking.mended_caution),
    # not on the whole clip, where a hand before a release would count against the fall
    mended: tuple[int, ...] = ()
    # the unit of each measured column (px, or m with a scale) and the amount of it in one unit of
    # the column as given (its spread): a measured path is fitted in these units; None: no unit
    units: tuple[str, ...] | None = None
    unit_scale: tuple[float, ...] | None = None
    # advice on what the user said that looks wrong, with its fix (no judgement of the estimate):
    # a warning line under the table
    hint: str | None = None

    def in_order(self, states: Sequence[str]) -> "Prepared":
        """The measured columns in the equation's state order, checked: a model may measure its
        states in any order, the encoder's latent dimension i is the equation's i-th state."""
        if self.states is None:
            return self
        names, states = tuple(self.states), list(states)
        if self.inputs.dim() != 4 or self.inputs.shape[1] != len(names) or tuple(self.inputs.shape[2:]) != (1, 1):
            raise ConfigError(f"a measured observation gives inputs of shape (T, k, 1, 1), one column per state it "
                              f"names ({', '.join(names)}); got {tuple(self.inputs.shape)}")
        unknown = [s for s in names if s not in states]
        if unknown or len(set(names)) != len(names):
            raise ConfigError(f"the observation measures {', '.join(names)}: each must be a different state of the "
                              f"equation ({', '.join(states)})")
        order = sorted(range(len(names)), key=lambda j: states.index(names[j]))
        units = None if self.units is None else tuple(self.units[j] for j in order)
        unit_scale = None if self.unit_scale is None else tuple(self.unit_scale[j] for j in order)
        return replace(self, inputs=self.inputs[:, order], states=tuple(names[j] for j in order), units=units,
                       unit_scale=unit_scale)


class ObservationModel:
    """The paper's observation: any function of the pixels the encoder can learn."""

    name = "any"
    architecture: str | None = None  # the encoder it needs; None: any (--encoder decides)
    # the latent is a measured coordinate (a centroid, a radius) read linearly: it cannot fold or
    # bend, and every restart reads the same path up to its own scale and offset
    measured = False
    # the latent is the state in its own physical units (radians for an angle): no gauge, no prior
    physical_units = False
    no_stretch = "no stretch is looked for"  # the stretch line's reason where applies("stretch") is False
    bend_floor: float | None = None  # the least bends' share of a constant's value (None: the interval's own)
    object: int | None = None  # the moving object it reads, k-th from the left (position@2); None: the strongest

    def __init__(self, subspace: bool = True):
        self.subspace = subspace
        self.reason = ""  # one line: why this model (set by resolve_observation)
        self.equation_states: tuple[str, ...] | None = None  # set by bind
        self.track = None  # the reader's track at the source's resolution (track.Track), set by use_track
        self.lengths = Lengths()  # how a measured length reads in px or metres, set by use_lengths

    def use_track(self, track) -> None:
        """Take the reader's track (track.Track, one row per frame the model will be given), which a
        model that measures a place reads instead of the shrunk frames; None for none. A model
        of one object (`position@2`) takes that object's path."""
        self.track = track.object(self.object) if track is not None and self.object is not None else track

    def use_lengths(self, lengths: Lengths) -> None:
        """Take how a length on the frames reads in source pixels, or metres with a scale stick."""
        self.lengths = lengths

    def bind(self, system) -> None:
        """Take the equation's states (resolve_observation calls this before any prepare)."""
        self.equation_states = tuple(system.states)

    def prepare(self, frames: torch.Tensor, architecture: str = "mlp", fit_frames: int | None = None) -> Prepared:
        """Raw float frames (T, C, H, W) -> what the encoder reads. The principal components come
        from the first fit_frames frames (the training range) only."""
        from .drawing import record, region_of_change
        # a free latent has no place in the image: the record says only where the frames change
        return Prepared(*signal_subspace(frames, architecture, fit_frames, self.subspace),
                        drawing=record(self.name, region=region_of_change(frames, fit_frames),
                                       states={s: self.name for s in self.equation_states or ()} or None))

    def encoder(self, architecture: str, in_shape: tuple[int, int, int], dim: int, seeds,
                output_mean: float = 0.0, output_std: float = 1.0) -> torch.nn.Module:
        return BatchedEncoder(architecture, in_shape, dim, seeds, output_mean=output_mean)

    def regulariser(self, z: torch.Tensor) -> torch.Tensor | None:
        """An extra loss term per restart, (R,), from the latents z (R, N, d); None for none."""
        return None

    def applies(self, check: str) -> bool:
        """Whether a check that depends on what the latent is applies to this model's fits.
        score: the restart score (does a free latent tell the frames apart; train/score.py: on a
        short fast clip the frames it compares never look alike, so it would call a right measured
        latent wrong). quiet: a latent that stops moving while the frames change follows only a
        start-up transient. rivals: restarts left out of the estimate may have ended in another
        basin (a measured latent is the same for every restart: those left out fitted it worse).
        perspective: re-read a one-dimensional measured path through a camera's perspective
        (perspective.perspective_check). trajectory: the whole-clip, halves and one-trajectory checks
        of a measured path (consistency.py). direct: the measured path is fitted by one trajectory
        itself (train/direct.py), every frame weighed alike, instead of training an encoder.
        periods: the latent must repeat with the frames (a free latent that repeats at another
        period is folded); a measured latent reads one part of what the frames show (the height
        of a can that also sways sideways at its own period), so its fit is held to the latent's
        own period instead. stretch: a measured path is searched for the stretch (the pieces) one
        trajectory explains: a place can be held, bounce, come to rest (no_stretch says why not)."""
        if check not in CHECKS:
            raise ValueError(f"unknown check {check!r}; one of {', '.join(CHECKS)}")
        free = not self.measured
        return {"score": free, "quiet": free, "rivals": free, "trajectory": self.measured,
                "perspective": False, "direct": self.measured, "periods": free, "stretch": self.measured}[check]

    @property
    def may_measure(self) -> bool:
        """Whether the frames may give a measured path (known before prepare: a light read
        linearly is one where a single pattern changes)."""
        return self.measured

    @property
    def can_bend(self) -> bool:
        """Whether the latent can bend where the frames do not hold it, which no residual shows
        (the interval then takes the bends' share: train/interval.py): a learned latent can."""
        return not self.measured

    @property
    def reads_lengths(self) -> bool:
        """Whether the measured latent is a length on the frames (px, or metres with a scale)."""
        return self.measured and not self.physical_units

    def fixes_scale(self) -> bool:
        """Whether the latent fixes the state's units, so that a constant whose value depends on
        them (g in a fall, k in a drain) is measured without calibration."""
        return self.physical_units

    def gauge_plan(self, plan: Mapping) -> dict:
        """The gauge between latent and state (fitode.eqparse.gauge.gauge_plan) as this model reads
        it: a state measured in its own units is the latent itself (scale 1, offset 0, not learned)."""
        if not self.physical_units:
            return dict(plan)
        from fitode.eqparse.gauge import StateGauge
        return {s: StateGauge(s, False, False, False, f"measured in its own units by the {self.name} observation")
                for s in plan}

    def describe(self) -> str:
        """One line: what the latent is (for `fitode check` and the run's header)."""
        entry = MODELS.get(self.name)
        line = entry.line if entry is not None else (type(self).__doc__ or "").strip().split("\n")[0]
        return f"{self.name}: {line}" if line else self.name


class MeasuredObservation(ObservationModel):
    """The camera measures the state: each input column is one state's coordinate, read linearly."""

    name = "measured"
    architecture = "linear"
    measured = True

    def encoder(self, architecture: str, in_shape: tuple[int, int, int], dim: int, seeds,
                output_mean: float = 0.0, output_std: float = 1.0) -> torch.nn.Module:
        """The linear read of the unit-variance columns, latent dimension i from column i (from
        column i mod k where fewer columns than states are measured), started at weight +-1 (the
        seed's sign) times the prior's spread: the latent then meets the prior from the first step,
        which a weight drawn at random would leave to an encoder learning rate made for thousands
        of weights. In physical units the latent is the columns themselves, with nothing to learn."""
        if self.physical_units:
            return FixedReadout(len(seeds), in_shape, dim)
        enc = super().encoder(architecture, in_shape, dim, seeds, output_mean)
        with torch.no_grad():
            w = enc.weights[0]  # (R, d, k)
            rows = torch.arange(w.shape[1], device=w.device)[:, None] % w.shape[2]
            own = rows == torch.arange(w.shape[2], device=w.device)[None, :]
            w.copy_(torch.where(own, torch.where(w >= 0, 1.0, -1.0) * output_std, torch.zeros_like(w)))
        return enc

    def column(self, z: torch.Tensor, components: np.ndarray, note: str, caution: str | None = None,
               drawing: dict[str, Any] | None = None, unit_scale: float | None = None) -> Prepared:
        """One measured column (T,) as the equation's first state (the one a single-state
        equation has); drawing: what was measured (drawing.py), its "states" filled in here;
        unit_scale: the length (px or m, self.lengths) one unit of z stands for, where z is one."""
        states = self.equation_states[:1] if self.equation_states else None
        if drawing is not None:
            drawing = dict(drawing)
            reading = drawing.pop("reading", drawing["kind"])
            if states:
                drawing["states"] = {states[0]: reading}
        units = (self.lengths.unit,) if unit_scale is not None else None
        return Prepared(z.reshape(-1, 1, 1, 1), components, 1, note, caution, states, drawing, units=units,
                        unit_scale=None if unit_scale is None else (float(unit_scale),))
