"""The position observation: the latent is affine in where something is along its line of motion."""
from __future__ import annotations

import math
import re
from dataclasses import replace
from typing import Mapping

import numpy as np
import torch

from fitode.errors import ConfigError

from .base import MeasuredObservation, ObservationModel, Prepared
from .drawing import points, record
from .tracking import STRAIGHT, centroids, line_of_motion, mend, straightness


AXES = {"x": "x", "y": "y", "h": "y", "z": "y"}  # a state named so reads that image axis (y, h, z: up)
# a named axis is always read (the user's word wins: a 25-degree throw's height carries 12% of
# its motion, and is what `y'' = -g` means); where it carries under BARELY of the motion's spread
# along its line (a spring bouncing up and down named x), that is said, with the name that reads
# the line of motion
BARELY = 0.05
# a single unnamed state's reading across its line of motion is fitted too where it carries at
# least this share of the motion
AXIS_SHARE = 0.3
TILT = 0.002  # a straight path this much longer than its reading along the named axis is said (tilt_hint)
FIRST_MOVE = 0.25  # the share of a path's range it must go from its start to say which way it moves
BENT = "; read through the camera's perspective"
FIRST_WAY = "positive the way it first moves"  # how a line's direction is said (_line, read_the_other_way)
TRACK_AGREE = 0.9  # the least correlation of the track's path with the shrunk frames' centroids' to read it


def first_move(path: torch.Tensor) -> float:
    """+1 or -1: the way a path (T,) first moves, by FIRST_MOVE of its range from where it starts
    (0 where it never does): the distance an unnamed state measures along a line runs that way,
    as a slide's, a fall's or a release's distance travelled does."""
    away = path - path[0]
    far = torch.nonzero(away.abs() >= FIRST_MOVE * float(path.max() - path.min())).flatten()
    return float(torch.sign(away[far[0]])) if len(far) and float(path.max() - path.min()) > 0 else 0.0


def read_the_other_way(prepared: Prepared) -> Prepared | None:
    """The prepared column of a single state read along its line of motion (_line), read the other
    way: its values, its drawn direction and its note turned (the trainer takes it where the
    equation's constants then come out positive as written: s'' = -a on a cart released at the top
    of its incline, which first moves down it). None where the column is no such reading."""
    drawing = prepared.drawing or {}
    # a single reader's drawing says its reading; the per-state reader's, each state's (observe.per_state)
    line_read = drawing.get("reading") == "line" or list((drawing.get("states") or {}).values()) == ["line"]
    if prepared.states is None or len(prepared.states) != 1 or not line_read:
        return None
    line = drawing.get("line") or {}
    turned = {**line, "direction": [-v for v in line.get("direction", [])]} if line else line
    note = re.sub(FIRST_WAY + r" \((\d+) degrees",
                  lambda m: ("positive against the way it first moves, the way the equation's constants come out "
                             f"positive as it writes them ({(int(m.group(1)) + 180) % 360} degrees"), prepared.note)
    return replace(prepared, inputs=-prepared.inputs, note=note, drawing={**drawing, "line": turned})


def axis_of(state: str) -> str | None:
    """The image axis a state's name says ("x" across, "y" up), or None."""
    return AXES.get(state)


def _mended(note: str, mended: int) -> str:
    """The note for frames whose centroid left the path of their neighbours (the caution is the
    trainer's, counted on the frames it fits: tracking.mended_caution)."""
    if mended:
        note += (f"; {mended} frame{'s' if mended != 1 else ''} whose centroid left the path of "
                 f"{'their' if mended != 1 else 'its'} neighbours read from them")
    return note


def _agreement(track: torch.Tensor, coarse: torch.Tensor, fit_frames: int | None) -> float:
    """How well the track's path (T, 2) runs as the shrunk frames' centroids (T, 2) do: the
    absolute correlation of their readings along the coarse line of motion, over the fit frames
    (both are affine in the same place where both follow the object)."""
    n = track.shape[0] if fit_frames is None else int(fit_frames)
    direction, along = line_of_motion(coarse.double(), n)
    full = (track.double() - track[:n].double().mean(dim=0)) @ direction
    pair = torch.stack([full[:n], along[:n]])
    if float(pair.std(dim=1).min()) == 0:
        return 0.0
    return abs(float(torch.corrcoef(pair)[0, 1]))


def _roughness(xy: torch.Tensor, fit_frames: int | None) -> float:
    """How much a path (T, 2) jumps from frame to frame against how far it goes: the mean
    absolute second difference along its line of motion over the path's range (a track that
    jumps to a hand and back is rough; a smooth motion, fast or slow, is not)."""
    n = xy.shape[0] if fit_frames is None else int(fit_frames)
    _, along = line_of_motion(xy.double(), n)
    along = along[:n]
    if len(along) < 3:
        return 0.0
    jumps = (along[2:] - 2 * along[1:-1] + along[:-2]).abs().mean()
    return float(jumps) / max(float(along.max() - along.min()), 1e-12)


def _strays(xy: torch.Tensor, fit_frames: int | None) -> float:
    """The share of a path's (T, 2) fit frames that leave the path of their neighbours along its
    line of motion (tracking.mend): the shrunk frames' centroid that jumps to something crossing
    the view for a while (a ball carried past a spring) leaves it more often than the reader's
    track, which follows the object through it."""
    n = xy.shape[0] if fit_frames is None else int(fit_frames)
    _, along = line_of_motion(xy.double(), n)
    return mend(along[:n])[1] / max(n, 1)


def _weak_axes(xy: torch.Tensor, axes: list[str]) -> list[int]:
    """The states whose named axis carries under BARELY of the spread along the line of motion."""
    _, along = line_of_motion(xy)
    spread = float(along.std())
    columns = {"x": xy[:, 0], "y": xy[:, 1]}
    return [i for i, axis in enumerate(axes) if float(columns[axis].std()) < BARELY * spread]


# the advice says "a straight line" only of a path a third as wide as the auto choice's STRAIGHT
# allows: a flat throw's parabola (17 degrees: 0.024 of its travel) is no slide (a generated cart: 0.0004)
HINT_STRAIGHT = STRAIGHT / 3


def _tilt_hint(xy: torch.Tensor, states: tuple[str, ...], axes: list[str]) -> str | None:
    """The advice for a single state named along an image axis whose path runs along a straight
    line tilted from that axis so far that the path along the line is TILT longer (a cart on an
    incline named x): the state is read along its axis, as named, and what that leaves out is said."""
    if len(states) != 1 or straightness(xy) >= HINT_STRAIGHT:
        return None
    direction, _ = line_of_motion(xy.double())
    along = abs(float(direction[0] if axes[0] == "x" else direction[1]))
    if along <= 0 or 1.0 / along - 1.0 < TILT:
        return None
    degrees = math.degrees(math.acos(min(along, 1.0)))
    return (f"{states[0]} is read {'across' if axes[0] == 'x' else 'up'} the image, as its name says; the object "
            f"moves along a straight line {degrees:.1f} degrees from that axis, where its path is "
            f"{100 * (1.0 / along - 1.0):.2g}% longer: where the equation is of the distance along that line (a slide, "
            "a cart on an incline), name the state s to measure it so")


# what a position reads: the change's centroid, the object followed by its appearance where the
# reader took that (fitode.video.follow: the change detector's path went from one thing to another),
# or a water line where the change is a band of water (fitode.video.waterline)
CENTROID = "the centroid of what differs most from the static scene ({pixels:.0f} pixels on average)"
FOLLOWED = "the object followed by its appearance ({pixels:.0f} pixels)"
LINE = "the water line (the moving end of the band of change)"


class PositionObservation(MeasuredObservation):
    """The camera sees where something is: the latent is affine in its image coordinates.

    The heat map is what differs from the clip's median frame (the static scene) by more than
    three times the noise (median absolute deviation) and by more than CORE of the frame's
    largest difference; its centroid moves with the object, exactly for a rigid object in view on
    a static background, whatever its shape, colour or contrast (tracking.py). An object that
    rests in one place for half the clip is part of the median frame: the centroid then mixes
    where it is with where it rests.
    A linear encoder reads the centroid's (x, y): the latent is a position along the line of
    motion, which no encoder can bend (a bend of a parabola is nearly another parabola, with
    another g). For a fall, a slide, a level that drops; a pendulum's latent would be L sin(theta).
    A state whose name says its axis (x across; y, h, z up) reads that axis instead, one column
    per state: `x'' = 0; y'' = -g` measures both coordinates of a throw.
    Where the reader measured a track at the source's resolution (fitode.video.track), the
    centroids are its; otherwise they come from the shrunk frames.
    """

    name = "position"

    def gauge_plan(self, plan: Mapping) -> dict:
        """The equation's gauge, with the zero of a state the equation pins (a spring's equilibrium,
        y'' = -w2*y - c*y') refined by the fit: the reading's zero is the path's mean, and a damped
        swing's mean is not where it settles (a generated spring, 4.6 periods: 0.32 px of a 12 px
        bounce, coverage.py seed 10; its one trajectory missed the whole clip by ten times the
        noise, the stretch search kept its first 1.3 s and w2 came out 2.4% low, TRUSTED). A state
        whose scale is learned too keeps its zero (a swing read as a position, L sin(theta): a
        shifted zero trades against the scale the swing's bend sets)."""
        from fitode.eqparse.gauge import StateGauge
        out = dict(plan)
        for s, g in plan.items():
            if g.zero_pinned and not g.offset_learned and not g.scale_learned:
                out[s] = StateGauge(s, False, True, g.positive,
                                    "its scale is free; its zero (the equilibrium) refined by the fit: the "
                                    "reading's zero is the path's mean", True)
        return out

    def applies(self, check: str) -> bool:
        # the perspective re-reading bends one column; a state per image axis is several
        if check == "perspective":
            states = self.equation_states or ()
            return len(states) <= 1 or not all(axis_of(s) for s in states)
        return super().applies(check)

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        out = ObservationModel.prepare(self, frames, architecture, fit_frames)  # the components the checks score against
        xy, pixels, unseen, _ = centroids(frames, fit_frames)
        where, disagree, what = "", "", CENTROID
        if self.object is not None:  # one object of several: the shrunk frames' centroid is the strongest's
            if self.track is None or len(self.track) != frames.shape[0]:
                raise ConfigError(f"{self.name}@{self.object}: the reader has no track of the objects (a video file "
                                  "or a folder of frames gives one)")
            unseen = self.track.unseen
            if unseen < frames.shape[0]:
                xy, pixels = torch.from_numpy(self.track.filled()).to(frames.device), self.track.area
                where = f"the reader's track of {self.track.note.split(';')[0]}: "
        elif self.track is not None and len(self.track) == frames.shape[0]:
            # the reader's track, at the source's resolution, where it runs as the frames' own
            # centroids do, or jumps less than they do: a track that jumps to something else (a
            # hand, the floor) is worse than the shrunk frames' coarser but whole view of the
            # change; centroids that jump to something crossing the view are worse than the track
            full = torch.from_numpy(self.track.filled()).to(frames.device)
            # where the shrunk frames lose the object (a 2-pixel ball) the track has no rival
            agree = 1.0 if unseen > 0.1 * frames.shape[0] else _agreement(full, xy, fit_frames)
            if (agree >= TRACK_AGREE or _roughness(full, fit_frames) <= 1.5 * _roughness(xy, fit_frames)
                    or _strays(full, fit_frames) < _strays(xy, fit_frames)):
                xy, pixels, unseen = full, self.track.area, self.track.unseen
                where = "the reader's track at the source's resolution: "
                what = LINE if self.track.line else FOLLOWED if self.track.followed else CENTROID
            else:
                disagree = (f"; the reader's track at the source's resolution was set aside: it follows the "
                            f"shrunk frames' centroids with a correlation of only {agree:.2f} and jumps more "
                            "from frame to frame")
        if unseen > 0.1 * frames.shape[0]:
            raise ConfigError(f"the position observation sees no change from the median frame in {unseen} of "
                              f"{frames.shape[0]} frames (the object stands still or leaves the view); "
                              "trim the clip to the motion (--start/--end) or observe 'any'")
        n_fit = xy.shape[0] if fit_frames is None else int(fit_frames)
        states = tuple(self.equation_states or ())
        axes = [axis_of(state) for state in states]
        if states and all(axes):
            prepared = self._axes(xy, states, axes, n_fit, out.components, pixels, where, frames.dtype, what)
            weak = _weak_axes(xy[:n_fit], axes)
            if weak:
                names = ", ".join(f"{states[i]} ({'across' if axes[i] == 'x' else 'up'})" for i in weak)
                prepared.caution = (f"{names} barely move{'s' if len(weak) == 1 else ''}: under "
                                    f"{100 * BARELY:.0f}% of the motion runs along the image axis the name says; "
                                    "name the state s to read its line of motion instead")
                prepared.note += "; " + prepared.caution
            else:
                prepared.hint = _tilt_hint(xy[:n_fit], states, axes)
        else:
            prepared = self._line(xy, n_fit, out.components, pixels, where, frames.dtype, what)
        if where:  # the reader's track is in the source's pixels, with a frame it did not see left out
            prepared.drawing.update(space="source",
                                    track=[None if np.isnan(x) else [float(x), float(y)] for x, y in self.track.xy])
        prepared.note += disagree
        return prepared

    def _line(self, xy: torch.Tensor, n_fit: int, components: np.ndarray, pixels: float, where: str,
              dtype: torch.dtype, what: str = CENTROID) -> Prepared:
        """One column: the position along the line of motion."""
        # the line of motion: a linear encoder of two collinear coordinates can cancel its own signal
        direction, raw = line_of_motion(xy, n_fit)
        path, mended = mend(raw, n_fit)
        if first_move(path[:n_fit]) < 0:  # the line's sign is the SVD's whim; a name gives none either
            direction, raw, path = -direction, -raw, -path
        z = path / path[:n_fit].std().clamp_min(1e-6)
        angle = float(torch.rad2deg(torch.atan2(-direction[1], direction[0]))) % 360  # image y points down
        note = (f"position: {where}{what.format(pixels=pixels)}, along its line of motion, {FIRST_WAY} "
                f"({angle:.0f} degrees from the image's x axis, counter-clockwise), read linearly")
        note = _mended(note, mended)
        frames = tuple(int(i) for i in torch.nonzero(path != raw).flatten())
        drawing = record(self.name, reading="line", track=points(xy), mended=list(frames) if mended else None,
                         line={"point": [float(v) for v in xy[:n_fit].mean(dim=0)],
                               "direction": [float(v) for v in direction]})
        spread = float(path[:n_fit].std().clamp_min(1e-6))
        unit = spread * self.lengths.factor(tuple(float(v) for v in direction), source=bool(where))
        prepared = replace(self.column(z.to(dtype), components, note, None, drawing, unit_scale=unit), mended=frames)
        across = self._across(xy, direction, n_fit, path[:n_fit].std().clamp_min(1e-6))
        if across is not None:
            prepared.other = (across.to(dtype), "across the line of motion")
            prepared.note += ("; the path moves across that line too (a state's name says no image axis: x across; "
                              "y, h, z up), so the reading across it is fitted as well")
        return prepared

    def _across(self, xy: torch.Tensor, direction: torch.Tensor, n_fit: int, unit: torch.Tensor) -> torch.Tensor | None:
        """The position across the line of motion (T,), in the along-reading's units (unit: its
        spread), where a single state reads the line and the path moves across it by at least
        AXIS_SHARE of its motion along it (a throw's height beside its flight); else None."""
        if len(self.equation_states or ()) != 1:
            return None
        normal = torch.stack([-direction[1], direction[0]]).to(xy.dtype)
        if float(normal[1]) > 0:  # up the image (its y points down): a throw's height, not its depth
            normal = -normal
        raw = (xy - xy[:n_fit].mean(dim=0)) @ normal
        path, _ = mend(raw, n_fit)
        if float(path[:n_fit].std()) < AXIS_SHARE * float(unit):
            return None
        return path / unit

    def _axes(self, xy: torch.Tensor, states: tuple[str, ...], axes: list[str], n_fit: int, components: np.ndarray,
              pixels: float, where: str, dtype: torch.dtype, what: str = CENTROID) -> Prepared:
        """One column per state, each the image axis its name says (x across, y/h/z up), so that
        `y'' = -g` reads the height of a throw, not its flight's main direction (the horizontal)."""
        columns, total, frames, scales = [], 0, set(), []
        for axis in axes:
            coordinate = xy[:, 0] if axis == "x" else -xy[:, 1]  # image y points down
            raw = coordinate - coordinate[:n_fit].mean()
            coordinate, mended = mend(raw, n_fit)
            total += mended
            frames.update(int(i) for i in torch.nonzero(coordinate != raw).flatten())
            spread = float(coordinate[:n_fit].std().clamp_min(1e-6))
            columns.append(coordinate / spread)
            scales.append(spread * self.lengths.factor((1.0, 0.0) if axis == "x" else (0.0, 1.0), source=bool(where)))
        named = ", ".join(f"{s} {'across' if a == 'x' else 'up'}" for s, a in zip(states, axes))
        note = (f"position: {where}{what.format(pixels=pixels)}, each state read along the image axis its name says ({named}), linearly")
        note = _mended(note, total)
        inputs = torch.stack(columns, dim=1).to(dtype).reshape(len(columns[0]), len(columns), 1, 1)
        drawing = record(self.name, track=points(xy), states={s: a for s, a in zip(states, axes)},
                         mended=sorted(frames) if frames else None)
        return Prepared(inputs, components, len(columns), note, None, states, drawing, mended=tuple(sorted(frames)),
                        units=(self.lengths.unit,) * len(columns), unit_scale=tuple(scales))

    def reread(self, prepared: Prepared, state: np.ndarray, perspective: dict, fit_frames: int) -> Prepared | None:
        """The path read through the camera's perspective that perspective.perspective_check found on a
        first training's state (T, 1), which is affine in the path: the encoder's new input is
        that state bent, at unit spread and in the path's orientation. None where a frame lies
        beyond the bend's pole."""
        from ..perspective import unbend

        bent = unbend(np.asarray(state, dtype=np.float64)[:, 0], perspective["c"], perspective["middle"])
        if bent is None:
            return None
        old = prepared.inputs.reshape(-1).double().cpu().numpy()
        z = (bent - bent[:fit_frames].mean()) / max(float(bent[:fit_frames].std()), 1e-12)
        if float(np.dot(z[:fit_frames], old[:fit_frames])) < 0:
            z = -z
        first = prepared.note.split(BENT)[0]  # read again once more: the new bend replaces the last one's words
        note = (f"{first}{BENT}: one trajectory of the equation fits "
                f"the whole path {perspective['misfit'][0] / max(perspective['misfit'][1], 1e-300):.1f}x better "
                f"when its ends are bent by {100 * perspective['bend_at_ends']:.1f}% (a camera that looks at the "
                "line of motion at an angle), so it was trained again on the path so corrected")
        inputs = torch.as_tensor(z, dtype=prepared.inputs.dtype, device=prepared.inputs.device).reshape(prepared.inputs.shape)
        return replace(prepared, inputs=inputs, note=note)
