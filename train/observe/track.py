"""A track: where the moving object was in every frame, measured by the reader on the decoded
frames before they were shrunk (fitode.video.track), in the source video's pixels.

Plain data, torch-free: the reader builds it, the observation models that measure a place
(position, angle) read it instead of the shrunk frames' centroids, and the measurement record
(Prepared.drawing) draws it on the frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Track:
    """xy: (T, 2) centroid (x right, y down) in source pixels per kept frame, NaN where nothing
    was seen; area: the object's mean area in source pixels; factor: the whole factor the frames
    were reduced by before measuring (1: the source's own resolution); note: one line on how."""

    xy: np.ndarray
    area: float
    factor: int
    note: str

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

    def head(self, n: int) -> "Track":
        """The first n frames (a trimmed or strided clip's track follows its frames)."""
        return Track(self.xy[:n], self.area, self.factor, self.note)
