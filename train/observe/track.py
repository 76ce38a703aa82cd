"""A track: where the moving object was in every frame, measured by the reader on the decoded
frames before they were shrunk (fitode.video.track), in the source video's pixels.

Plain data, torch-free: the reader builds it, the observation models that measure a place
(position, angle) read it instead of the shrunk frames' centroids, and the measurement record
(Prepared.drawing) draws it on the frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fitode.errors import ConfigError


@dataclass
class Track:
    """xy: (T, 2) centroid (x right, y down) in source pixels per kept frame, NaN where nothing
    was seen; area: the object's mean area in source pixels; factor: the whole factor the frames
    were reduced by before measuring (1: the source's own resolution); note: one line on how."""

    xy: np.ndarray
    area: float
    factor: int
    note: str
    # the moving objects' paths (T, 2) from left to right (fitode.video.track.objects), for the
    # states that name their object (`position@2`); xy is the strongest path's
    objects: tuple[np.ndarray, ...] = ()
    # xy is the object followed by its appearance (fitode.video.follow), not the change's centroid
    followed: bool = False
    # xy is a water line, the moving end of a band of change (fitode.video.waterline), not a centroid
    line: bool = False
    # the object enters the view at the first frame, leaves it after the last (the frames were
    # read where it is in view: fitode.pipeline.in_view), so no hold before nor rest after
    enters: bool = False
    leaves: bool = False

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    @property
    def unseen(self) -> int:
        """Frames where nothing was seen."""
        return int(np.isnan(self.xy[:, 0]).sum())

    def filled(self) -> np.ndarray:
        """xy with each unseen frame read from its seen neighbours (linear in time; an end takes
        the nearest seen frame). All NaN where no frame was seen."""
        xy = np.array(self.xy, dtype=np.float64)
        seen = ~np.isnan(xy[:, 0])
        if seen.all() or not seen.any():
            return xy
        t = np.arange(len(xy))
        for j in range(2):
            xy[~seen, j] = np.interp(t[~seen], t[seen], xy[seen, j])
        return xy

    def in_view(self, gap: int, far: float) -> tuple[int, int]:
        """[first, last + 1): the frames where the object is in view (a puck that slides in from
        the edge and out again is seen only in between): of the runs of seen frames no more than
        `gap` frames apart and no farther apart than `far` pixels a frame, the one with the most (a
        flicker of noise seen before the object came or after it left is not it, nor what the
        change detector finds at a ruler's edge in the frames without it); (0, 0) where it never
        was."""
        seen = np.flatnonzero(~np.isnan(self.xy[:, 0]))
        if not len(seen):
            return 0, 0
        frames = np.diff(seen)
        step = np.hypot(*np.diff(self.xy[seen], axis=0).T)
        runs = np.split(seen, np.flatnonzero((frames > gap) | (step > far * frames)) + 1)
        best = max(runs, key=len)
        return int(best[0]), int(best[-1]) + 1

    def head(self, n: int) -> "Track":
        """The first n frames (a trimmed or strided clip's track follows its frames)."""
        return Track(self.xy[:n], self.area, self.factor, self.note, tuple(p[:n] for p in self.objects), self.followed,
                     self.line, self.enters, self.leaves and n >= len(self))

    def place(self, k: int) -> tuple[float, float]:
        """The k-th moving object's (1-based, from the left) median place (x, y) in source pixels."""
        path = self.objects[k - 1]
        return float(np.nanmedian(path[:, 0])), float(np.nanmedian(path[:, 1]))

    def taken(self) -> int | None:
        """Which of the moving objects (1-based, from the left) xy follows: the one whose path lies
        nearest it (the median distance over the frames both place) within the object's size;
        None where none does (the object tracker followed something none of the change's paths is)."""
        best, near = None, max(3.0, float(np.sqrt(max(self.area, 1.0))))
        for k, path in enumerate(self.objects, 1):
            both = np.isfinite(path[:, 0]) & np.isfinite(self.xy[:, 0])
            if both.sum() >= 3:
                d = float(np.median(np.hypot(*(path[both] - self.xy[both]).T)))
                if d <= near:
                    best, near = k, d
        return best

    def others(self, model: str) -> str | None:
        """One line naming the other moving objects and the flag that reads one of them, for a fit
        whose numbers are not trusted: the change detector's strongest path is not always the
        object the equation is about (a hand that lets a ball go, an arm beside it, a person
        behind). None where the tracker sees a single moving object."""
        if len(self.objects) < 2:
            return None
        k = self.taken()
        where = ", ".join("{} about ({:.0f}, {:.0f})".format(i, *self.place(i)) for i in range(1, len(self.objects) + 1))
        flags = [f"--observe {model}@{i}" for i in range(1, len(self.objects) + 1) if i != k]
        took = (f"the reader took object {k}; where the equation is about another" if k else
                "the reader's path is none of theirs; where the equation is about one of them")
        return (f"the tracker sees {len(self.objects)} moving objects (from the left, their median place in source "
                f"pixels (x, y down): {where}) and {took}, name it: {' or '.join(flags)}")

    def object(self, k: int) -> "Track":
        """The track of the k-th moving object from the left (1-based); ConfigError where fewer
        are in view."""
        if not 1 <= k <= len(self.objects):
            raise ConfigError(f"object {k} is asked for, but the tracker sees {len(self.objects)} moving object"
                              f"{'s' if len(self.objects) != 1 else ''} in view for at least half the clip")
        path = self.objects[k - 1]
        seen = np.isfinite(path[:, 0])
        note = (f"object {k} of {len(self.objects)} from the left (about x = {self.place(k)[0]:.0f} "
                f"pixels), in view in {int(seen.sum())} of {len(path)} frames; {self.note}")
        return Track(path, self.area, self.factor, note, self.objects)
