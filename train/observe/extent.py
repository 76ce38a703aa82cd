"""How large an object looks in each frame: the apparent radius behind the size and distance
observation models.

Only the object's outline changes where it grows or shrinks, so the measure works on the
frames' changes, not on a static scene (an object that fills the middle of every frame leaves no
background to compare with there). Frame t's outline lies in the ring between its neighbours'
outlines, the pixels where frame t+1 differs from frame t-1 (the clip's two end frames are
extrapolated from their neighbours); the strongest of those changes (EDGE_CORE of the frame's largest and over three times the noise)
are kept as weights.

A circle fitted to one ring (the algebraic fit of Kasa) gives the radius and centre exactly for a
round outline, and from any visible arc of it, so an object cut by the frame's edge is still
measured; for another rigid shape the fitted radius is its scale up to a constant. But a ring
under a pixel wide at a distant object has too few pixels to fix a centre, and a centre off by a
pixel moves the radius of a small arc by as much. The path of the centre fixes it: an object that
moves along a straight line in space, as anything falling or thrown along the line of sight does,
is seen by a pinhole camera with its centre at c_inf + k * r, affine in its apparent radius r
(both go as 1 / distance). So the centres of every frame are fitted as one affine function of
the radius (robustly, each frame weighted by its ring's mass), each frame's radius is then the
weighted mean distance of the middle half of its ring from that centre, and the two steps alternate.
On the realistic free-fall scenes at 64x114 (radius 2 to 43 pixels, partly outside the frame at
first) the radii come out within 1-5% rms of the truth while they are over SMALL pixels; below
that the optical blur shrinks the ring's middle (by about sigma^2 / 2r for a blur of sigma
pixels: 15-20% at 2 pixels), and the observation warns.

The ring's middle is not the outline, though: the change is weighed by how much each pixel
changes, and a shaded ball changes more where its dark limb left than where its lit face did,
so the ring's middle leans outwards by a fifth of the step between frames (+1.5% where a
falling ball shrinks 4 pixels a frame, g +2 to +6% on the generated falls). So each frame's
outline is then placed where it is (outline_radii): along rays from the centre, the mean
distance of the frame's colour from the background just outside falls from the object's level
to the background's, and the outline is where it is half-way (a blurred edge's middle, wherever
the light falls on the object). Measured on the coverage bench's generated falls (seeds 7 and 8,
16 clips, read in colour at their source size, g from a parabola through two true distances):
g +2.3% on average with the ring alone (rms 3.8%), +0.0% (rms 1.8%) with the outline; at a short
side of 128, -0.1% (rms 1.6%); at 64, +1.0% (rms 4.0%). In gray the same outline is -4 to -6%
off (that yellow ball is as light as the floor, and its shading is what shows), so frames in gray
keep the ring; the pipeline reads a size or distance again in colour
(fitode.pipeline.extent_in_detail). The half-way level has a bias of its own where the object's
colour moves away from the background's towards its middle (the object's level is taken a few
pixels inside): tests/test_observe.py's gray disc, 0.9 in its middle and 0.6 at its rim on a 0.4
wall, stacked into three channels, reads 0.2-0.5 px inside (rms 2.5% against the ring's 0.3%).
The steepest fall of the same profile does not have it, but measured worse on the falls (rms 2.2%
against 1.8% at the source's size, 3.1% against 1.6% at 128 px).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import torch
import torch.nn.functional as F

from .tracking import noise_level

EDGE_CORE = 0.5
ROUNDS = 5
SMALL = 3.0  # pixels: below this apparent radius the blur biases the measure
# the outline is looked for this far (pixels) beyond the ring radii of a frame and its neighbours,
# and the object's and the background's levels are taken over BAND pixels inside and outside that
OUTLINE_PAD = 2.0
OUTLINE_BAND = 3.0
OUTLINE_STEP = 0.25  # pixels between samples along a ray
# an outline is placed only where the object stands out from the background by this many times
# the background's own level (its texture and noise), and kept only where most frames have one
OUTLINE_CONTRAST = 2.0
OUTLINE_SHARE = 0.5


@torch.no_grad()
def apparent_radii(frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, int]:
    """(T,) apparent radius in pixels of what grows or shrinks in frames (T, C, H, W), its (T, 2)
    centre (x, y), and how many frames show no change at their outline."""
    gray = frames.mean(dim=1).double()
    if gray.shape[0] < 3:
        raise ValueError("the size of an object needs at least 3 frames")
    change = torch.cat([gray[1:2] - gray[:1], gray[2:] - gray[:-2], gray[-1:] - gray[-2:-1]]).abs()
    noise = noise_level(change)
    floor = torch.maximum(3 * noise, EDGE_CORE * change.flatten(1).max(dim=1).values)[:, None, None]
    heat = torch.where(change > floor, change, torch.zeros_like(change))
    mass = heat.sum(dim=(1, 2))
    unseen = int((mass <= 0).sum())
    # the ring's pixels only (a few percent of the frame), as one list over all frames
    frame, row, col = torch.nonzero(heat, as_tuple=True)
    ring = _Ring(frame, col.to(heat.dtype), row.to(heat.dtype), heat[frame, row, col], heat.shape[0])
    radius, centre = _circles(ring)
    for _ in range(ROUNDS):
        centre = _straight_path(radius, centre, mass)
        rho = ((ring.x - centre[ring.frame, 0]) ** 2 + (ring.y - centre[ring.frame, 1]) ** 2).sqrt()
        radius = _middle_mean(rho, ring)
    # an end frame's ring is one-sided and, where the object has nearly stopped changing, faint
    # enough for stray noise to place it anywhere: its two neighbours extrapolate it instead
    if radius.shape[0] >= 4:
        radius = torch.cat([2 * radius[1:2] - radius[2:3], radius[1:-1], 2 * radius[-2:-1] - radius[-3:-2]])
    return outline_radii(frames, radius, centre), centre, unseen


@torch.no_grad()
def outline_radii(frames: torch.Tensor, radius: torch.Tensor, centre: torch.Tensor) -> torch.Tensor:
    """(T,) the radius of each frame's outline about its centre (see the module docstring), searched
    for near the ring radius of the frame and its neighbours, in frames in colour (in gray the ring
    radii are returned: a yellow ball on a grey floor differs little from it in gray, g -6%). A
    frame with no outline to find (too little of it in view, too faint) keeps its ring radius
    rescaled as the others' outlines were; where most frames have none, the ring radii are returned."""
    n_frames, channels, h, w = frames.shape
    if channels < 3:
        return radius
    ring = radius.double()
    out = torch.full_like(ring, float("nan"))
    for t in range(n_frames):
        near = ring[max(t - 1, 0):t + 2]
        lo, hi = max(float(near.min()) - OUTLINE_PAD, 1.0), float(near.max()) + OUTLINE_PAD
        out[t] = _outline(frames[t].double(), centre[t].double(), lo, hi, h, w)
    found = torch.isfinite(out) & (ring > 0)
    if int(found.sum()) < OUTLINE_SHARE * n_frames:
        return radius
    ratio = (out[found] / ring[found]).median()
    return torch.where(torch.isfinite(out), out, ring * ratio).to(radius.dtype)


def _outline(img: torch.Tensor, centre: torch.Tensor, lo: float, hi: float, h: int, w: int) -> float:
    """One frame's (C, H, W) outline radius between lo and hi about centre (x, y), or NaN."""
    rays = int(min(max(2 * math.pi * hi, 32), 720))
    theta = torch.arange(rays, dtype=img.dtype) * (2 * math.pi / rays)
    rho = torch.arange(max(lo - OUTLINE_BAND, 0.5), hi + OUTLINE_BAND + OUTLINE_STEP, OUTLINE_STEP, dtype=img.dtype)
    xs = centre[0] + theta.cos()[:, None] * rho[None]
    ys = centre[1] + theta.sin()[:, None] * rho[None]
    whole = ((xs >= 0) & (xs <= w - 1) & (ys >= 0) & (ys <= h - 1)).all(dim=1)
    if int(whole.sum()) < max(8, rays // 10):
        return math.nan
    grid = torch.stack([2 * xs[whole] / max(w - 1, 1) - 1, 2 * ys[whole] / max(h - 1, 1) - 1], dim=-1)
    profile = F.grid_sample(img[None], grid[None], mode="bilinear", align_corners=True)[0]  # (C, rays, rho)
    outside, inside = rho > hi, rho < lo
    if not bool(outside.any()) or not bool(inside.any()):
        return math.nan
    background = profile[:, :, outside].mean(dim=2, keepdim=True)
    apart = (profile - background).norm(dim=0).mean(dim=0)  # (rho,): how far from the background
    level_in, level_out = float(apart[inside].mean()), float(apart[outside].mean())
    if not level_in > OUTLINE_CONTRAST * level_out:
        return math.nan
    half = 0.5 * (level_in + level_out)
    window = torch.nonzero((rho >= lo - OUTLINE_STEP) & (rho <= hi + OUTLINE_STEP)).flatten()
    above = apart[window[:-1]] >= half
    below = apart[window[:-1] + 1] < half
    crossing = torch.nonzero(above & below).flatten()
    if crossing.numel() == 0:
        return math.nan
    j = int(window[int(crossing[-1])])  # the outermost: a face's shading inside may cross too
    a, b = float(apart[j]), float(apart[j + 1])
    return float(rho[j]) + OUTLINE_STEP * (a - half) / (a - b)


class _Ring(NamedTuple):
    """The pixels of every frame's ring of change: their frame, x, y and weight (the change)."""
    frame: torch.Tensor
    x: torch.Tensor
    y: torch.Tensor
    weight: torch.Tensor
    frames: int

    def per_frame(self, values: torch.Tensor) -> torch.Tensor:
        """(T, ...) the sum of values (N, ...) over each frame's pixels."""
        out = torch.zeros((self.frames,) + tuple(values.shape[1:]), dtype=values.dtype)
        return out.index_add_(0, self.frame, values)


def _middle_mean(values: torch.Tensor, ring: _Ring) -> torch.Tensor:
    """Per frame, the weighted mean of its ring pixels' values between the weighted quartiles: stray noise
    pixels far from a faint ring's outline do not move it, as they would a mean, and it varies
    smoothly as a thin ring crosses the pixel grid, where a median jumps between the few
    distances the ring's pixels have."""
    # sorted by frame, then by value within the frame
    span = float(values.max()) + 1.0 if values.numel() else 1.0
    order = torch.argsort(values + ring.frame.to(values.dtype) * span)
    v, w, f = values[order], ring.weight[order], ring.frame[order]
    total = ring.per_frame(w)
    cum = w.cumsum(dim=0)
    start = torch.cumsum(total, dim=0) - total  # the weight of the frames before each
    cum = cum - start[f]
    before = cum - w
    t = total[f].clamp_min(1e-300)
    # the share of each value's weight that falls between the quartiles
    inside = (torch.minimum(cum, 0.75 * t) - torch.maximum(before, 0.25 * t)).clamp_min(0)
    return ring.per_frame(inside * v) / ring.per_frame(inside).clamp_min(1e-300)


def _circles(ring: _Ring) -> tuple[torch.Tensor, torch.Tensor]:
    """Each frame's weighted algebraic circle fit, x^2 + y^2 + D x + E y + F = 0: (T,) radii and
    (T, 2) centres."""
    a = torch.stack([ring.x, ring.y, torch.ones_like(ring.x)], dim=1)
    b = -(ring.x ** 2 + ring.y ** 2)
    ata = ring.per_frame(ring.weight[:, None, None] * a[:, :, None] * a[:, None, :]) \
        + 1e-9 * torch.eye(3, dtype=a.dtype)
    atb = ring.per_frame(ring.weight[:, None] * a * b[:, None])
    p = torch.linalg.solve(ata, atb)
    cx, cy = -p[:, 0] / 2, -p[:, 1] / 2
    return (cx ** 2 + cy ** 2 - p[:, 2]).clamp_min(0).sqrt(), torch.stack([cx, cy], dim=1)


def _straight_path(radius: torch.Tensor, centre: torch.Tensor, mass: torch.Tensor) -> torch.Tensor:
    """The centres as one affine function of the radius, fitted with Cauchy weights so that a
    frame whose ring was too thin to place its centre does not pull the rest."""
    x = torch.stack([torch.ones_like(radius), radius], dim=1)
    weight = mass.clone()
    for _ in range(3):
        root = weight.sqrt()[:, None]
        coef = torch.linalg.lstsq(x * root, centre * root).solution
        fit = x @ coef
        miss = (centre - fit).norm(dim=1)
        scale = 1.4826 * miss.median() + 1e-6
        weight = mass / (1 + (miss / (2 * scale)) ** 2)
    return fit
