"""The size and distance observations: the latent is affine in an apparent radius (extent.py),
or in its reciprocal."""
from __future__ import annotations

import torch

from fitode.errors import ConfigError

from .base import MeasuredObservation, ObservationModel, Prepared
from .drawing import points, record
from .extent import SMALL, apparent_radii


# the short side of the frames the principal components come from (fitode.video's default read)
COMPONENTS_SHORT = 64


def _as_read(frames: torch.Tensor) -> torch.Tensor:
    """frames (T, C, H, W) in gray and shrunk by area to COMPONENTS_SHORT on the short side, as the
    first read gives them: a size is read again in colour at the source's size for its outline
    (fitode.pipeline.extent_in_detail), where the principal components of every pixel in double
    precision would take gigabytes on a long clip and tell the starts nothing more."""
    gray = frames.mean(dim=1, keepdim=True) if frames.shape[1] > 1 else frames
    h, w = gray.shape[-2:]
    scale = COMPONENTS_SHORT / min(h, w)
    if scale >= 1:
        return gray
    size = (max(1, round(h * scale)), max(1, round(w * scale)))
    return torch.nn.functional.interpolate(gray, size=size, mode="area")


class SizeObservation(MeasuredObservation):
    """The camera sees how large something looks: the latent is affine in its apparent radius
    (extent.py), for what grows or shrinks in place (the paper's scale videos, a balloon, a
    spreading drop). Read linearly like a position: no encoder can bend the size into another
    law. (The distance model is the perspective of a size: no perspective re-reading here.)"""

    name = "size"
    how = "read linearly"

    def reading(self, radius: torch.Tensor) -> torch.Tensor:
        return radius

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        # the components the starts and checks read, from the frames as the first read shrinks them
        out = ObservationModel.prepare(self, _as_read(frames), architecture, fit_frames)
        radius, centre, unseen = apparent_radii(frames)
        if unseen > 0.1 * frames.shape[0]:
            raise ConfigError(f"the {self.name} observation sees no outline change in {unseen} of {frames.shape[0]} "
                              "frames (the object keeps its size); trim the clip to the motion (--start/--end) or "
                              "observe 'any'")
        if float(radius.min()) < 0.5:
            raise ConfigError(f"the {self.name} observation measured an apparent radius of {float(radius.min()):.2f} "
                              "pixels: nothing in view grows or shrinks; observe 'position' or 'any'")
        n_fit = radius.shape[0] if fit_frames is None else int(fit_frames)
        value = self.reading(radius)
        z = (value - value[:n_fit].mean()) / value[:n_fit].std().clamp_min(1e-12)
        smallest = float(radius[:n_fit].min())
        note = (f"{self.name}: the apparent radius of the outline that grows or shrinks ({smallest:.1f} to "
                f"{float(radius[:n_fit].max()):.1f} pixels), {self.how}")
        caution = None
        if smallest < SMALL:
            caution = (f"the object is {smallest:.1f} pixels in radius at its smallest, and the blur shrinks a "
                       f"measured radius under {SMALL:g} pixels (by 15-20% at 2): give a larger --size or "
                       "--roi around the object")
        reach = radius[:, None].clamp_min(0)
        lo, hi = (centre - reach).min(dim=0).values, (centre + reach).max(dim=0).values
        drawing = record(self.name, reading="radius" if self.name == "size" else "1/radius", track=points(centre),
                         radii=[float(r) for r in radius], region=[float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])])
        # a radius in pixels has a length's unit; its reciprocal (the distance model) has none to give
        unit = (float(value[:n_fit].std()) * 0.5 * (self.lengths.factor((1.0, 0.0)) + self.lengths.factor((0.0, 1.0)))
                if self.name == "size" else None)
        return self.column(z.to(frames.dtype), out.components, note, caution, drawing, unit_scale=unit)


class DistanceObservation(SizeObservation):
    """The camera sees how large something looks as it moves along the line of sight: a pinhole
    camera sees an object of radius R at distance d with radius f R / d, so the latent is affine
    in the reciprocal of the apparent radius (a fall towards or away from the camera: the
    paper's free-fall-scale videos)."""

    name = "distance"
    how = "read as its reciprocal, affine in the distance from the camera"

    def reading(self, radius: torch.Tensor) -> torch.Tensor:
        return 1.0 / radius

    def applies(self, check: str) -> bool:
        # the reciprocal of a shrinking radius grows noisier along the path: one trajectory that
        # weighs every frame alike follows the noisy end (g +10.7% on the realistic fall, where the
        # trained encoder gave +1.3%), so this reading keeps the encoder
        return False if check == "direct" else super().applies(check)
