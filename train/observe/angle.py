"""The angle observation: the latent is the angle, in radians, about the centre the tracked
point's path bends about (a pendulum's pivot), from the direction it hangs in."""
from __future__ import annotations

from typing import Mapping

import numpy as np
import torch

from fitode.errors import ConfigError

from .base import MeasuredObservation, ObservationModel, Prepared
from .circle import Circle, fit_circle, on_one_radius
from .tracking import MEND_PIXELS, MEND_SIGMAS, MENDED_MAX, centroids, mend_strays

BENDS = 2.0  # sagitta over scatter under which a path does not bend about any centre (ConfigError)
# the share by which a loosely fitted pivot may move a constant, from which it is a caution: an
# angle's scale off by a share e (the radius's standard error) moves a pendulum's period by about
# e theta^2 / 8 at amplitude theta, and so L by e theta^2 / 4
SCALE_EFFECT = 0.005
NOT_PLANAR = 0.03  # scatter over radius from which the path is not one circle (a swing seen at a slant, a spring)


class AngleObservation(MeasuredObservation):
    """The camera sees a swing: the latent is the angle of the tracked point about the pivot.

    Where the object is in each frame comes from the reader's track at the source's resolution
    (fitode.video.track) when there is one, else from the shrunk frames (tracking.centroids).
    A circle is fitted to that path robustly (circle.py; the pivot may lie outside the frame),
    and the latent is the point's angle about its centre, measured from the direction it hangs
    in (the mean angle over whole swings): the state in its own units, so a pendulum's L comes
    out at any amplitude, with no gauge to learn and no prior. A position would read L sin(theta).
    """

    name = "angle"
    physical_units = True

    def __init__(self, subspace: bool = True):
        super().__init__(subspace)
        self.scale_matters = True  # the equation's constants change when the angle is rescaled (set by bind)

    def bind(self, system) -> None:
        super().bind(system)
        from fitode.eqparse.gauge import gauge_plan  # sympy: only when a fit is set up
        try:
            self.scale_matters = gauge_plan(system)[system.states[0]].scale_learned
        except Exception:  # noqa: BLE001 - the symmetry test can fail on unusual equations: assume it matters
            self.scale_matters = True

    def gauge_plan(self, plan: Mapping) -> dict:
        """The angle in radians (scale 1), its zero refined by the fit where the equation pins it
        (a pendulum's sin(theta)): the direction the path hangs in is read from the swing's turning
        points, and on a short clip of a small swing it is off by a little of the swing (0.0024
        rad of a 0.12 rad swing over 1.5 periods, generated pendulum, coverage.py seed 13 clip 9):
        sin(theta) of a shifted angle is no trajectory of the equation, so each half of the clip
        gave its own L (1.157 and 1.208 for 1.1792) and the verdict was ambiguous though L was
        right. A zero the equation leaves free stays where it was read."""
        from fitode.eqparse.gauge import StateGauge
        return {s: StateGauge(s, False, g.zero_pinned, False, "measured in radians by the angle observation"
                              + ("; the direction it hangs in refined by the fit" if g.zero_pinned else ""),
                              g.zero_pinned)
                for s, g in plan.items()}

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        out = ObservationModel.prepare(self, frames, architecture, fit_frames)  # the components the checks score against
        n = int(frames.shape[0])
        n_fit = n if fit_frames is None else int(fit_frames)
        xy, where = self.path(frames, fit_frames)
        xy, carried, strays = on_one_radius(xy)
        xy, mended = _mended_off_the_arc(xy, n_fit)
        circle = fit_circle(xy[:n_fit])
        if circle is None or circle.bend < BENDS:
            bend = "lies on a line" if circle is None else f"bows {circle.sagitta:.2g} pixels, {circle.bend:.1f}x its scatter"
            raise ConfigError(f"the angle observation needs a path that bends about a pivot; this one {bend}: "
                              "observe 'position' for a motion along a line")
        theta, hang = angles(xy, circle, n_fit)
        note = (f"angle: {where}, about the pivot ({circle.centre[0]:.1f}, {circle.centre[1]:.1f}) at radius "
                f"{circle.radius:.1f} pixels (scatter {circle.scatter:.2f}, the arc bows {circle.sagitta:.1f}), in "
                f"radians from the direction it hangs in; swings up to {np.degrees(np.abs(theta[:n_fit]).max()):.0f} degrees")
        caution = _caution(circle, float(np.abs(theta[:n_fit]).max())) if self.scale_matters else None
        if carried:
            note += (f"; in {carried} frame{'s' if carried != 1 else ''} the point was nearer the pivot along the "
                     "swing's direction (the string, where the change lost the bob), read in its direction from the pivot")
        if strays:
            note += (f"; {strays} frame{'s' if strays != 1 else ''} inside the arc off that direction read from "
                     "their neighbours")
        if carried + strays > MENDED_MAX * n_fit:
            # the string's centroid leans off the bob's direction (0.019 rad on the generated light bob,
            # its scatter 0.014 rad against the bob's 0.004), which no share of the interval holds:
            # read without --calibrate, L -0.30% +- 0.22% there, TRUSTED
            caution = (f"{carried + strays} of {n_fit} frames were read on the string or from their neighbours, where "
                       "the change lost the bob: the string's direction leans off the bob's by an amount the interval "
                       "does not hold; a bob that stands out from the wall is read in every frame")
        if mended:
            note += f"; {mended} frame{'s' if mended != 1 else ''} off the path of the neighbours read from them"
            if mended > MENDED_MAX * n_fit:
                caution = (f"{mended} of {n_fit} frames had a centroid off the path of their neighbours and were "
                           "read from them: something else changes in the view as much as the object; give --roi")
        prepared = self.column(torch.as_tensor(theta, dtype=frames.dtype, device=frames.device), out.components,
                               note, caution)
        prepared.drawing = self.drawing(circle, hang, xy)
        return prepared

    def drawing(self, circle: Circle, hang: float, xy: np.ndarray) -> dict:
        """The measurement record (drawing.py): in source pixels where the track is the reader's,
        else in the frames' pixels (fitode.measurement maps those)."""
        states = {s: "angle" for s in (self.equation_states or ())[:1]}
        if self.track is not None:
            track = [None if np.isnan(x) else [float(x), float(y)] for x, y in self.track.xy]
            space = "source"
        else:
            track, space = [[float(x), float(y)] for x, y in xy], "frames"
        return {"kind": self.name, "space": space, "states": states, "track": track,
                "pivot": [circle.centre[0], circle.centre[1]], "radius": circle.radius, "hanging": float(hang),
                "scale_error": float(circle.radius_error) if np.isfinite(circle.radius_error) else None,
                # the pivot's covariance (pixels^2): the interval re-reads the angles about it moved (pivot_moves)
                "pivot_cov": None if circle.centre_cov is None else [[circle.centre_cov[0], circle.centre_cov[1]],
                                                                     [circle.centre_cov[1], circle.centre_cov[2]]]}

    def path(self, frames: torch.Tensor, fit_frames: int | None) -> tuple[np.ndarray, str]:
        """(T, 2) where the object is, and one line on where that came from."""
        if self.track is not None:
            if len(self.track) != frames.shape[0]:
                raise ConfigError(f"the track has {len(self.track)} frames for {frames.shape[0]} frames")
            if self.track.unseen > 0.1 * len(self.track):
                raise ConfigError(f"the angle observation sees nothing move in {self.track.unseen} of "
                                  f"{len(self.track)} frames; trim the clip to the motion (--start/--end)")
            return self.track.filled(), f"the tracked point ({self.track.note})"
        xy, pixels, unseen, _ = centroids(frames, fit_frames)
        if unseen > 0.1 * frames.shape[0]:
            raise ConfigError(f"the angle observation sees no change from the median frame in {unseen} of "
                              f"{frames.shape[0]} frames; trim the clip to the motion (--start/--end)")
        return xy.double().cpu().numpy(), f"the centroid of what differs most from the static scene ({pixels:.0f} pixels)"


def _mended_off_the_arc(xy: np.ndarray, n_fit: int) -> tuple[np.ndarray, int]:
    """The track with its strays read from their neighbours (mend_strays), but only those off the
    arc the whole path lies on (the robust circle of the unmended path, MEND_SIGMAS of its scatter
    and MEND_PIXELS away): a fast swing sampled coarsely (the paper's motion video, 15 pixels a
    frame) misses the local parabolas at its turns, and reading those frames from their neighbours
    would cut the corners of a right path; something else in view is off the arc."""
    mended, count = mend_strays(xy, n_fit)
    arc = fit_circle(np.asarray(xy)[:n_fit]) if count else None
    if arc is None:
        return mended, count
    raw = np.asarray(xy, dtype=np.float64)
    off = np.abs(np.hypot(raw[:, 0] - arc.centre[0], raw[:, 1] - arc.centre[1]) - arc.radius)
    keep = np.any(mended != raw, axis=1) & (off <= max(MEND_SIGMAS * arc.scatter, MEND_PIXELS))
    mended = np.where(keep[:, None], raw, mended)
    return mended, count - int(keep.sum())


def angles(xy: np.ndarray, circle: Circle, n_fit: int | None = None) -> tuple[np.ndarray, float]:
    """The angle (T,) of each point about the circle's centre, from the direction the path hangs
    in, and that direction (radians, image axes: x right, y down). The direction is the middle of
    the swing's turning points over the first n_fit points: each half swing's farthest point
    (between two crossings of the direction), each taken halfway between its neighbours on the
    other side (a decaying swing's turning points shrink). The mean angle over whole swings leaned
    to one side on a large swing (4.9 degrees at 42 degrees, coverage.py --cases pendulum-large
    clip 4, where the turning points' middle is 0.1 degrees off): sin(theta) of a shifted angle is
    no trajectory of the equation, and L came out 2.5% off with +-7%."""
    xy = np.asarray(xy, dtype=np.float64)
    n_fit = len(xy) if n_fit is None else int(n_fit)
    raw = np.unwrap(np.arctan2(xy[:, 1] - circle.centre[1], xy[:, 0] - circle.centre[0]))
    hang = float(np.median(raw[:n_fit]))
    for _ in range(3):
        side = raw[:n_fit] >= hang  # (a sign would be 0 on the point at the median, and miss a crossing)
        cross = np.flatnonzero(side[1:] != side[:-1])
        if len(cross) < 3:
            break
        turns = np.array([_turn(raw[a + 1:b + 1], hang) for a, b in zip(cross[:-1], cross[1:])])
        middles = turns[1:-1] / 2 + (turns[:-2] + turns[2:]) / 4 if len(turns) >= 3 else turns
        hang = float(np.mean(middles))
    return raw - hang, hang


TURN_POINTS = 5  # a half swing's turning point: the median of its farthest few (a stray is one of them)


def _turn(half: np.ndarray, hang: float) -> float:
    """The angle a half swing turns at: the median of its TURN_POINTS points farthest from hang,
    so that a stray frame at the turn does not set it (the same few fall short of the turn on
    either side, which the middle of two turns cancels)."""
    far = np.argsort(np.abs(half - hang))[-TURN_POINTS:]
    return float(np.median(half[far]))


def _caution(circle: Circle, amplitude: float) -> str | None:
    effect = amplitude ** 2 / 4 * circle.radius_error
    if effect > SCALE_EFFECT:
        return (f"the path bows only {circle.bend:.1f}x its scatter about the fitted pivot, which sets the angle's "
                f"scale to {100 * circle.radius_error:.1f}%: at a swing of {np.degrees(amplitude):.0f} degrees that "
                f"may move a constant by {100 * effect:.1f}%")
    if circle.scatter > NOT_PLANAR * circle.radius:
        return (f"the path strays {100 * circle.scatter / circle.radius:.1f}% of its radius from one circle (a swing "
                "that is not in a plane facing the camera, or a point that is not the swinging object's)")
    return None


def pivot_moves(x: np.ndarray, drawing: Mapping | None, frames: tuple[int, int]) -> list[np.ndarray]:
    """How the measured angle x (T, 1) over the track's frames [first, last) changes when the pivot
    moves by one standard deviation along each principal axis of its covariance (the drawing's
    pivot_cov): a pivot off along the hanging direction scales small angles and bends large ones
    (a 120-degree swing's damping read 0.16% high about a pivot 0.06 pixels off), one off across
    it tilts them. Each change is taken about its mean (the hanging direction is read again).
    [] where the drawing is not an angle's or has no covariance."""
    drawing = drawing or {}
    cov, track = drawing.get("pivot_cov"), drawing.get("track")
    if drawing.get("kind") != "angle" or cov is None or not track:
        return []
    first, last = frames
    x = np.asarray(x, dtype=np.float64).reshape(-1)
    centre, radius, hang = np.asarray(drawing["pivot"], dtype=np.float64), float(drawing["radius"]), float(drawing["hanging"])
    xy = np.array([p if p is not None else [np.nan, np.nan] for p in track], dtype=np.float64)[first:last]
    raw = np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0]) - hang
    seen = np.isfinite(raw)
    if len(x) != len(raw) or seen.sum() < 3:
        return []
    sign = 1.0 if np.corrcoef(np.unwrap(raw[seen]), x[seen])[0, 1] >= 0 else -1.0
    phi = hang + sign * x  # the direction of each frame's point from the pivot, in image axes
    values, vectors = np.linalg.eigh(np.asarray(cov, dtype=np.float64))
    moves = []
    for value, vector in zip(values, vectors.T):
        d = np.sqrt(max(float(value), 0.0)) * vector
        moved = np.arctan2(radius * np.sin(phi) - d[1], radius * np.cos(phi) - d[0])
        change = sign * np.angle(np.exp(1j * (moved - phi)))
        moves.append((change - change.mean())[:, None])
    return moves
