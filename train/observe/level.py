"""The level observation: the latent is the height of a water line, a horizontal edge that moves
up or down (a tank that drains or fills).

A level is no object: what changes from the clip's median frame is the band of water between
the level and its median place, as wide as the tank, whose centroid mixes the level with
anything floating on it and whose area vanishes near the median frame (the position
observation's reading of a generated drain: k 49% off). The level is read as the shift of the
row profile instead: the tank's columns averaged per row give a profile that is air above the
line and water below; where the line rises by s rows, the sum of the profile's change from the
median profile over a band of rows that holds every place of the line is s times the step
across the band (the median profile's last row minus its first). That is exact for any shape
of the line (a meniscus, a highlight on the surface, a ball floating on it) that moves with it,
and it sums the whole band's pixels, so it reads a fraction of a pixel on shrunk frames (on the
coverage bench's drains: 0.04-0.06 pixels rms about the true level, 1% of a 4-pixel travel).
Where the reader has read the water line itself at the source's resolution (the track's `line`:
fitode.video.waterline), the level is that line's height in source pixels instead: the sum over a
band takes the step across it from the band's end rows, and on the shared bottle at half its
resolution the band ran down to the bottle's floor (read_level: a travel of 318 pixels for 159).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from fitode.errors import ConfigError

from .base import MeasuredObservation, ObservationModel, Prepared
from .drawing import record
from .tracking import noise_level

CORE = 0.5  # the tank's core: the columns around the most changing one that change at least this share of it
TANK = 4.0  # ... and the tank: the columns around it whose band of rows changes this many spreads beyond the rest
BAND = 0.25  # the rows whose largest change is at least this share of the largest row's are the line's band
MARGIN = 3  # rows added to each side of the band that changes, so that its ends lie on the plateaus
STEP = 6.0  # the step across the band must be this many times the profile's noise


@dataclass
class Level:
    """A level read from the frames: its height (T,) in rows up, the tank's columns [left, right]
    and the band of rows [top, bottom] it was read over, and the step across that band in grey
    levels (air minus water, signed)."""

    height: torch.Tensor
    columns: tuple[int, int]
    rows: tuple[int, int]
    step: float

    @property
    def travel(self) -> float:
        return float(self.height.max() - self.height.min())

    @property
    def is_level(self) -> bool:
        """A line that moves within the band it was read over: a lamp that brightens in place has
        no step across its band, so the sum of its change would read as a travel far beyond it."""
        return self.travel <= self.rows[1] - self.rows[0]


@torch.no_grad()
def read_level(frames: torch.Tensor, fit_frames: int | None = None) -> Level | None:
    """The water line's height in frames (T, C, H, W), in rows up from its median place; None where
    the frames show no step across the band that changes (no level to read)."""
    gray = frames.double().mean(dim=1)
    n = gray.shape[0] if fit_frames is None else int(fit_frames)
    change = gray - gray[:n].median(dim=0).values
    # only what changes beyond the noise: summed over a tall frame, the noise of every column
    # would outweigh a few rows of water line
    heat = change[:n].abs()
    columns = torch.where(heat > 3 * noise_level(heat), heat, torch.zeros_like(heat)).sum(dim=(0, 1))
    left, right = _run(columns, floor=CORE * float(columns.max()))
    profile = gray[:, :, left:right + 1].mean(dim=2)
    rows = _band(profile, n)
    if rows is None:
        return None
    # the tank is wider than the core, which is where a floating ball drifts: every column next to
    # it whose band of rows changes beyond what the columns away from the tank show (their median
    # and TANK times their spread)
    per_column = change[:n, rows[0]:rows[1] + 1].sum(dim=1).abs().mean(dim=0)
    middle = per_column.median()
    spread = 1.4826 * (per_column - middle).abs().median()
    left, right = _run(per_column, floor=float(middle + TANK * spread))
    profile = gray[:, :, left:right + 1].mean(dim=2)
    rows = _band(profile, n) or rows
    median = profile[:n].median(dim=0).values
    step = float(median[rows[1]] - median[rows[0]])
    noise = float(noise_level((profile[:n] - median).abs())) + 1e-12
    if abs(step) < STEP * noise:
        return None
    total = (profile[:, rows[0]:rows[1] + 1] - median[rows[0]:rows[1] + 1]).sum(dim=1)
    height = total / step
    return Level(height, (left, right), rows, step)


def _run(values: torch.Tensor, floor: float) -> tuple[int, int]:
    """The run of indices around the largest value whose values are at least floor."""
    j = int(values.argmax())
    a = b = j
    while a > 0 and float(values[a - 1]) >= floor:
        a -= 1
    while b < len(values) - 1 and float(values[b + 1]) >= floor:
        b += 1
    return a, b


def _band(profile: torch.Tensor, n: int) -> tuple[int, int] | None:
    """The rows [top, bottom] where the row profile (T, H) changes beyond its noise and by BAND of
    its largest change, widened by MARGIN; None where no row does. (The water's shade, darker with
    depth below its surface, changes a little down to the tank's floor as the level drops: that
    is no part of the line's band.)"""
    change = (profile[:n] - profile[:n].median(dim=0).values).abs()
    largest = change.amax(dim=0)
    strong = torch.nonzero(largest > max(6 * float(noise_level(change)), BAND * float(largest.max()))).flatten()
    if len(strong) == 0:
        return None
    top = max(int(strong.min()) - MARGIN, 0)
    bottom = min(int(strong.max()) + MARGIN, profile.shape[1] - 1)
    return (top, bottom) if bottom > top else None


class LevelObservation(MeasuredObservation):
    """The camera sees a water line: the latent is affine in its height (read_level), for a tank
    that drains or fills. Read linearly like a position: no encoder can bend it."""

    name = "level"

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        out = ObservationModel.prepare(self, frames, architecture, fit_frames)  # the components the checks score against
        n_fit = frames.shape[0] if fit_frames is None else int(fit_frames)
        if self.track is not None and self.track.line and len(self.track) == frames.shape[0]:
            return self._line(frames, out.components, n_fit)
        level = read_level(frames, fit_frames)
        if level is None or not level.is_level:
            raise ConfigError("the level observation sees no water line (a horizontal edge that moves up or down "
                              "across the changing columns); observe 'position' or 'any'")
        h = level.height
        z = (h - h[:n_fit].mean()) / h[:n_fit].std().clamp_min(1e-12)
        (left, right), (top, bottom) = level.columns, level.rows
        note = (f"level: the height of the water line, the shift of the row profile of columns {left}-{right} over "
                f"rows {top}-{bottom} (a step of {255 * abs(level.step):.0f} grey levels), travelling "
                f"{level.travel:.1f} pixels, read linearly")
        drawing = record(self.name, reading="level", levels=[float(v) for v in h],
                         region=[float(left) - 0.5, float(top) - 0.5, float(right) + 0.5, float(bottom) + 0.5])
        return self.column(z.to(frames.dtype), out.components, note, None, drawing,
                           unit_scale=float(h[:n_fit].std()) * self.lengths.factor((0.0, 1.0)))

    def _line(self, frames: torch.Tensor, components, n_fit: int) -> Prepared:
        """The level from the reader's water line (fitode.video.waterline), in source pixels: the
        line's own row in every frame at the source's resolution, where the shrunk frames' row
        profile sums the whole band (whose far rows darken with the water's depth)."""
        xy = self.track.filled()
        h = torch.as_tensor(-(xy[:, 1] - xy[:n_fit, 1].mean()), dtype=torch.float64)
        z = (h - h[:n_fit].mean()) / h[:n_fit].std().clamp_min(1e-12)
        travel = float(h[:n_fit].max() - h[:n_fit].min())
        note = (f"level: the height of the water line in the reader's track at the source's resolution, travelling "
                f"{travel:.1f} source pixels, read linearly")
        # drawn as a position along the vertical, up: the line's place on the frames, the fitted trajectory on it
        drawing = record(self.name, reading="line", space="source",
                         track=[None if np.isnan(x) else [float(x), float(y)] for x, y in self.track.xy],
                         line={"point": [float(v) for v in xy[:n_fit].mean(axis=0)], "direction": [0.0, -1.0]})
        return self.column(z.to(frames.dtype), components, note, None, drawing,
                           unit_scale=float(h[:n_fit].std()) * self.lengths.factor((0.0, 1.0), source=True))
