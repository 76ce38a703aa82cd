"""Which observation model a fit uses: an instance as given, a name (or one per state), or the
auto choice from the equation and a look at the frames. The same rule in prose, for
`fitode check`, is catalog.auto_rule.

The auto choice looks at where the frames change (the heat map of the position observation): a
change whose centroid travels farther than the changing region's own size is something that
moves; one that moves ONE_WAY (|rank correlation| of its travel with time) is a fall, a slide or
a level that drops; a change that stays in place is light.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
import torch

from .angle import AngleObservation
from .base import ObservationModel
from .brightness import BrightnessObservation
from .catalog import AUTO, model_class, parse_observe, split_object
from .circle import Circle, fit_circle, on_one_radius
from .level import Level, LevelObservation, read_level
from .position import PositionObservation, axis_of
from .subspace import SUBSPACE_JUMP
from .track import Track
from .tracking import (ONE_WAY, STRAIGHT, centroids, covers_one_way, line_of_motion, noise_level, one_way,
                       one_way_run, straightness)

STRONG = 0.25  # frames whose largest change is at least this share of the clip's largest
LOOK_FRAMES = 256
# a back-and-forth path swings about a centre where its arc bows SWING times the uncertainty of
# that bow (circle.Circle.significance) and it runs along the arc, its scatter across it under
# THIN of the arc's length (a spring that bounces while it swings fills an area)
SWING = 8.0
THIN = 0.05
# and it turns through at least SPAN radians about that centre (a swing of +-2.9 degrees): a
# straight path bowed a few pixels by the lens or by stray frames fits a circle too, with a
# centre far away (the real drop: 35567 pixels, 0.048 rad)
SPAN = 0.1
MIN_LEVEL_TRAVEL = 1.0  # pixels a water line must travel to be read as a level
EXACT_ARC = 0.01  # pixels: a path this close to its arc was read as an angle about a pivot, not as a place


def named_model(name: str, light: str = "auto") -> ObservationModel:
    """The catalog's model of this name, with its options ("position@2": of the second moving
    object from the left)."""
    name, k = split_object(name)
    cls = model_class(name)
    model = cls(light) if issubclass(cls, BrightnessObservation) else cls()
    model.object = k
    return model


def resolve_observation(spec: str | Mapping[str, str] | ObservationModel | None, system,
                        frames: torch.Tensor | None = None, light: str = "auto", encoder: str = "auto",
                        source: str = "as asked", track: Track | None = None,
                        n_train: int | None = None) -> ObservationModel:
    """The observation model a fit uses, bound to the equation's states and given the reader's
    track, with its reason: an instance as given, a name, one name per state ({state: name} or
    "x=position;y=size"), or "auto" (None): position where the change moves one way, angle where
    a single state's change swings back and forth about a centre, position where the change
    moves otherwise and every state's name says its image axis (y'' = -w2*y - c*y' for a bouncing
    spring, x'' = 0; y'' = -g for a throw), brightness for a single
    first-order linear equation whose frames brighten or dim as one, any otherwise (and wherever
    an encoder other than linear was asked for). source: where a named model came from, for its
    reason. track: the reader's track of every frame the fit will use (the auto choice looks at
    its first n_train), None where there is none."""
    model = _resolved(spec, system, frames, light, encoder, source,
                      None if track is None else track.head(len(track) if n_train is None else n_train))
    model.bind(system)
    if track is not None:
        model.use_track(track)
    if frames is not None:
        # the camera's curve is a choice like the model: resolved here, once, on the training frames
        for part in getattr(model, "parts", {model.name: model}).values():
            if isinstance(part, BrightnessObservation):
                part.settle(frames)
    return model


def _resolved(spec, system, frames, light, encoder, source, track) -> ObservationModel:
    if isinstance(spec, ObservationModel):
        spec.reason = spec.reason or f"{spec.name} (as given)"
        return spec
    name = parse_observe(AUTO if spec is None else spec)
    if isinstance(name, dict) and len(name) == 1 and len(system.states) == 1:
        name = next(iter(name.values()))  # the one state's model named for it is that model, checks and all
    if isinstance(name, dict):
        from .per_state import PerStateObservation
        model = PerStateObservation({state: named_model(n, light) for state, n in name.items()}, system.states)
        model.reason = f"{model.name} ({source})"
        return model
    if name != AUTO:
        model = named_model(name, light)
        model.reason = f"{name} ({source})"
        return model
    if encoder not in ("auto", "linear"):
        model = ObservationModel()
        model.reason = f"any (auto: the {encoder} encoder was asked for)"
        return model
    from fitode.eqparse.identify import power_symmetric  # sympy: only when a fit is set up
    seen = look(frames, track) if frames is not None else None
    level = _level(system, frames)
    if level is not None:
        model = LevelObservation()
        model.reason = (f"level (auto: a single first-order state named along the image's vertical "
                        f"({system.states[0]} up), and the frames show a horizontal edge that moves "
                        f"{level.travel:.1f} pixels one way (rank correlation {one_way(level.height):.2f} with time): "
                        "its height is the state)")
        return model
    if seen is not None and seen.moves and seen.one_way >= ONE_WAY:
        model = PositionObservation()
        model.reason = (f"position (auto: the change moves {seen.travel:.0f} pixels, {seen.travel / seen.size:.0f}x its "
                        f"size, one way (rank correlation {seen.one_way:.2f} with time): a free encoder could bend "
                        "its path into one with other constants)")
        return model
    if seen is not None and seen.moves and seen.runs_one_way:
        model = PositionObservation()
        model.reason = (f"position (auto: the tracked object moves {seen.travel:.0f} pixels, {seen.travel / seen.size:.0f}x "
                        f"its size, and one run of its path covers {seen.run[0]:.0%} of its travel one way, no run "
                        f"the other way more than {seen.run[1]:.0%} (rank correlation {seen.one_way:.2f} with time over "
                        "the whole clip): a free encoder could bend its path into one with other constants)")
        return model
    if seen is not None and seen.swings and len(system.states) == 1:
        model = AngleObservation()
        c = seen.arc()
        model.reason = (f"angle (auto: the change swings back and forth (rank correlation {seen.one_way:.2f} with "
                        f"time) along an arc about a centre {c.radius:.0f} pixels away that bows {c.sagitta:.1f} "
                        f"pixels, " + (f"{c.significance:.0f}x its uncertainty (scatter {c.scatter:.1f} pixels over "
                                       f"{c.points} frames)" if c.scatter >= EXACT_ARC else
                                       # a string's direction read about its pivot (fitode.video.rod) lies on one circle
                                       f"its {c.points} points on it within {EXACT_ARC} pixels") +
                        ": the angle about that centre is the state in radians)")
        return model
    if seen is not None and seen.travels and all(axis_of(state) for state in system.states):
        model = PositionObservation()
        named = ", ".join(f"{state} {'across' if axis_of(state) == 'x' else 'up'}" for state in system.states)
        how = (f"the change moves {seen.travel:.0f} pixels, {seen.travel / seen.size:.0f}x its size" if seen.moves else
               f"the tracked object moves {seen.followed:.1f}x its own size")
        model.reason = f"position (auto: {how}, and the state's name says the image axis it is measured along ({named}))"
        return model
    if seen is not None and seen.travels and seen.straight and not seen.swings and _lengths(system):
        model = PositionObservation()
        model.reason = (f"position (auto: the tracked object moves {seen.followed:.0f}x its size back and forth along "
                        f"a straight line, its scatter across it {100 * seen.across:.2g}% of its travel, and the equation "
                        f"leaves {system.states[0]}'s scale and zero free: its place along that line is the state)")
        return model
    if not power_symmetric(system):
        model = ObservationModel()
        model.reason = "any (auto: the paper's free encoder; the equation's constants do not follow a bend of the latent)"
        return model
    if seen is not None and not seen.moves:
        model = BrightnessObservation(light)
        why = (f"one pattern that brightens or dims: the first singular value is {seen.gap:.0f}x the second"
               if seen.gap >= SUBSPACE_JUMP else f"its centre moves {seen.travel:.1f} pixels, less than its size")
        model.reason = f"brightness (auto: a single first-order linear equation, and the change stays in place, {why})"
    else:
        model = ObservationModel()
        model.reason = ("any (auto: the change moves back and forth; the linear encoder keeps the rate)"
                        if seen is not None else "any (auto: no frames to look at)")
    return model


def _lengths(system) -> bool:
    """A single state, named along no image axis, whose scale and zero the equation leaves free (a
    length along a track: s'' = -a; not an angle under sin, nor a level under sqrt)."""
    if len(system.states) != 1 or axis_of(system.states[0]):
        return False
    from fitode.eqparse.gauge import gauge_plan  # sympy: only when a fit is set up
    gauge = gauge_plan(system)[system.states[0]]
    return not (gauge.scale_learned or gauge.offset_learned or gauge.positive)


def _level(system, frames: torch.Tensor | None) -> Level | None:
    """The water line a single first-order state named along the vertical (h' = -k*sqrt(h)) is
    read from, where the frames show one that moves one way; None otherwise."""
    if frames is None or len(system.states) != 1 or axis_of(system.states[0]) != "y":
        return None
    if system.orders[system.states[0]] != 1:
        return None
    step = max(1, frames.shape[0] // LOOK_FRAMES)
    level = read_level(frames[::step])
    if level is None or not level.is_level or level.travel < MIN_LEVEL_TRAVEL:
        return None
    return level if one_way(level.height) >= ONE_WAY else None


@dataclass
class Look:
    """Where the frames change: how far the change's centroid travels, the changing region's size
    (the square root of its area), both in pixels, and how one-way the travel runs in time."""

    travel: float
    size: float
    one_way: float
    gap: float = 1.0  # the frames' first singular value over their second
    circle: Circle | None = None  # the circle the path bends about (None: a line, or too few points)
    # the path's points (T, 2) whose circle is fitted on first need (arc): a path that runs one way
    # is decided without it, and without the import of scipy that the robust fit takes
    bent: np.ndarray | None = None
    # the shares of the tracked path's travel its longest one-way run covers and its longest run the
    # other way (tracking.one_way_run; (0, 0): no track)
    run: tuple[float, float] = (0.0, 0.0)
    # the tracked path's travel over the tracked object's size, both in source pixels (0: no track):
    # a small swing's string sweeps a region larger than the bob's travel in the shrunk frames (a
    # generated 8-degree swing: 14 pixels of travel against 24), while its bob travels 6 times its size
    followed: float = 0.0
    # the path's scatter across its line of motion over its travel along it (inf: not measured)
    across: float = float("inf")

    @property
    def runs_one_way(self) -> bool:
        """One run of the tracked path covers most of its travel one way and it never comes far back."""
        return covers_one_way(self.run)

    @property
    def moves(self) -> bool:
        """The change travels farther than its size, and it is not one pattern that brightens
        and dims: a lamp's frames lie on one line in pixel space (a clear gap after the first
        singular value), even where its brightest core seems to wander."""
        return self.travel > self.size and self.gap < SUBSPACE_JUMP

    def arc(self) -> Circle | None:
        """The circle the path bends about (circle, or fitted now to the points kept in bent, those
        on an arc nearer its centre carried out to it: circle.on_one_radius)."""
        if self.circle is None and self.bent is not None:
            self.circle, self.bent = fit_circle(on_one_radius(self.bent)[0]), None
        return self.circle

    @property
    def travels(self) -> bool:
        """It moves, or the tracked object travels farther than its own size: a short piece of a
        motion (a cart's last flight alone, 27 pixels up and back) moves less than the change's
        region in the shrunk frames (the cart and its ghost in the median frame)."""
        return self.moves or (self.followed > 1 and self.gap < SUBSPACE_JUMP)

    @property
    def straight(self) -> bool:
        """The path runs along a straight line: its scatter across it is under STRAIGHT of its travel."""
        return self.across < STRAIGHT

    @property
    def swings(self) -> bool:
        """It moves back and forth along an arc that clearly bends about a centre. A path one run of
        which covers its travel one way is no swing however it bends (a flat throw held before it
        and resting after it: rank correlation 0.86 with time, its parabola bowing 40 pixels)."""
        if not (self.travels and self.one_way < ONE_WAY) or self.runs_one_way:
            return False
        c = self.arc()
        return (c is not None and c.significance >= SWING and c.thinness <= THIN and c.radius_error < 0.5
                and c.span >= SPAN)


@torch.no_grad()
def look(frames: torch.Tensor, track: Track | None = None) -> Look:
    """The look behind the auto choice, from at most LOOK_FRAMES frames spread over the clip, and
    the reader's track of them where there is one (its path and size, in source pixels)."""
    step = max(1, frames.shape[0] // LOOK_FRAMES)
    sub = frames[::step]
    xy, _, _, peak = centroids(sub)
    # frames that barely differ from the static scene (a lamp at its median brightness) have a
    # centroid of noise: only the frames with a clear change say where it is
    strong = peak >= STRONG * peak.max()
    xy = xy[strong]
    # the size of everything that changes (a lamp's whole glow, not only its brightest core)
    gray = sub.double().mean(dim=1)
    diff = (gray - gray.median(dim=0).values).abs()
    pixels = float((diff[strong] > 3 * noise_level(diff)).sum(dim=(1, 2)).double().mean()) if bool(strong.any()) else 0.0
    flat = gray.reshape(gray.shape[0], -1)
    flat = flat - flat.mean(dim=0)
    sv = torch.linalg.eigvalsh(flat @ flat.T).flip(0).clamp_min(0).sqrt()
    gap = float(sv[0] / sv[1].clamp_min(1e-12)) if len(sv) > 1 else 1.0
    if xy.shape[0] < 3 or float((xy - xy.mean(dim=0)).abs().max()) == 0:
        return Look(0.0, max(pixels, 1.0) ** 0.5, 0.0, gap)
    _, path = line_of_motion(xy)
    seen = Look(float(path.max() - path.min()), max(pixels, 1.0) ** 0.5, one_way(path), gap)
    if track is not None and track.unseen < 0.1 * len(track):
        # the same look at the source's resolution: the shrunk frames' centroids say whether
        # something moves, the track how its path runs and bends
        filled = track.filled()
        full = torch.from_numpy(filled)
        _, path = line_of_motion(full)
        # a track that jumps to something else in some frames (a hand, the floor) looks back and
        # forth; the shrunk frames' centroids of the same clip may still see it run one way
        travel = float(path.max() - path.min())
        seen = Look(seen.travel, seen.size, max(seen.one_way, one_way(path[::step])), gap,
                    run=one_way_run(path.numpy()), followed=travel / max(track.area, 1.0) ** 0.5,
                    bent=filled, across=straightness(full))
    elif seen.moves:
        seen.bent = xy.double().cpu().numpy()
    return seen

