"""Observation models: what the camera measures about the state, and the encoder that reads it.

An observation model owns the whole path from raw frames to latent: `prepare` turns the frames
into what the encoder reads (once per fit), `encoder` builds the (batched) encoder for R
restarts, and `regulariser` may add a term to the loss. The default, "any", is the paper's: a
free encoder (mlp, cnn or linear) on the mean-removed frames, restricted to their signal
subspace. fitode.fit accepts a name or an instance, as PySINDy's estimator accepts its parts.

The signal subspace. An encoder with more free weights than frames can draw any curve out of
pixel noise (a linear encoder on 64x85 frames of a dimming lamp gave a decay rate of the wrong
sign). The frames are projected on their leading principal components first. Where the
singular values drop by a clear gap (one ratio of neighbours above SUBSPACE_JUMP: a lamp that
dims is one component, then video noise), the components above the gap are kept. Otherwise
(a moving object spreads over many components with no gap) those above the noise floor:
SUBSPACE_GAP times the median singular value of the second quarter of the spectrum, where only
noise and the tail of the motion live; at most SUBSPACE_CAP. An mlp or linear encoder then reads the
k coefficients, which is the same function class as reading the projected frames (its first
layer absorbs the projection) at a fraction of the cost; a cnn reads the projected frames.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch

from fitode.errors import ConfigError
from fitode.video.light import srgb_to_linear

from .config import LIGHT_CHOICES, OBSERVE_CHOICES
from .encoders import BatchedEncoder, normalise_frames

SUBSPACE_GAP = 3.0
SUBSPACE_JUMP = 3.0
SUBSPACE_CAP = 32
SCORE_COMPONENTS = 8


@dataclass
class Prepared:
    """The frames as the encoder reads them, and what the checks need from the same analysis."""

    inputs: torch.Tensor  # (T, C, H, W) or (T, k, 1, 1)
    components: np.ndarray  # (T, SCORE_COMPONENTS) leading principal-component coefficients
    rank: int
    note: str  # one line: the subspace kept and why
    caution: str | None = None  # a reason the measurement may be off (an object too small), for the verdict


class ObservationModel:
    """The paper's observation: any function of the pixels the encoder can learn."""

    name = "any"
    architecture: str | None = None  # the encoder it needs; None: any (--encoder decides)
    # The latent is a geometric measurement (a centroid, a radius) read linearly: it cannot fold
    # or bend, so the restart score (train/score.py), which asks whether a free latent follows
    # the frames, has nothing to judge; and on a short fast clip (a 30-frame fall) the frames a
    # few steps apart that the score compares never look alike, so it would call a right
    # latent wrong.
    geometric = False
    perspective = False  # may the trainer re-read the latent through a camera's perspective (holds.perspective_check)?
    physical_units = False  # the latent is the state in its own physical units (no scale or offset to learn)

    @property
    def measured(self) -> bool:
        return self.geometric

    def applies(self, check: str) -> bool:
        """Whether a check that depends on what the latent is applies to this model: "score",
        "quiet" and "rivals" judge a learned latent; "trajectory" a measured one; "perspective"
        re-reads a measured path through a camera's perspective."""
        return {"score": not self.measured, "quiet": not self.measured, "rivals": not self.measured,
                "trajectory": self.measured, "perspective": self.perspective}[check]

    def __init__(self, subspace: bool = True):
        self.subspace = subspace
        self.reason = ""  # one line: why this model (set by resolve_observation)

    def prepare(self, frames: torch.Tensor, architecture: str = "mlp", fit_frames: int | None = None) -> Prepared:
        """Raw float frames (T, C, H, W) -> what the encoder reads. The principal components come
        from the first fit_frames frames (the training range) only."""
        x = normalise_frames(frames)
        n_fit = x.shape[0] if fit_frames is None else int(fit_frames)
        flat = x.reshape(x.shape[0], -1).double()
        mean = flat[:n_fit].mean(dim=0, keepdim=True)
        centred = flat - mean
        fit = centred[:n_fit]
        evals, evecs = torch.linalg.eigh(fit @ fit.T)  # the T x T Gram matrix is small where pixels are many
        order = torch.argsort(evals, descending=True)
        sv = evals[order].clamp_min(0).sqrt()
        k_max = int((sv > 1e-9 * sv[0]).sum()) if sv[0] > 0 else 0
        floor = float(sv[len(sv) // 4: max(len(sv) // 2, len(sv) // 4 + 1)].median()) if len(sv) >= 8 else 0.0
        above = int((sv > SUBSPACE_GAP * floor).sum()) if floor > 0 else k_max
        head = sv[: min(SUBSPACE_CAP, k_max) + 1]
        jumps = (head[:-1] / head[1:].clamp_min(1e-300)) if len(head) > 1 else head[:0]
        jump = int(torch.argmax(jumps)) if len(jumps) else -1
        gapped = jump >= 0 and float(jumps[jump]) > SUBSPACE_JUMP
        rank = (jump + 1) if gapped else max(1, min(above, SUBSPACE_CAP, k_max)) if k_max else 1
        # pixel directions of the leading components: V = X^T U / s
        keep = order[: max(rank, SCORE_COMPONENTS)]
        u = evecs[:, keep]
        s = sv[: keep.numel()].clamp_min(1e-12)
        basis = (fit.T @ u) / s  # (pixels, K), orthonormal columns
        coefs = centred @ basis  # (T, K): every frame, the held-out ones too
        components = coefs[:, :SCORE_COMPONENTS].cpu().numpy()
        if not self.subspace:
            return Prepared(x, components, k_max, "the encoder reads every pixel (no signal subspace)")
        plural = "s" if rank != 1 else ""
        if gapped:
            note = (f"signal subspace: {rank} principal component{plural} of the frames (the singular values "
                    f"drop {_times(float(jumps[jump]))} after the {rank}{_th(rank)})")
        else:
            ratio = f"{float(sv[rank - 1] / floor):.1f}x" if floor > 0 else "n/a"
            note = (f"signal subspace: {rank} principal component{plural} of the frames "
                    + (f"(capped at {SUBSPACE_CAP}; " if above > SUBSPACE_CAP else "(")
                    + f"the last kept stands {ratio} above the noise floor)")
        head = coefs[:, :rank]
        if architecture == "cnn":
            inputs = (head @ basis[:, :rank].T + mean).reshape(x.shape).to(x.dtype)
        else:
            inputs = (head / s[0] * np.sqrt(n_fit)).to(x.dtype).reshape(x.shape[0], rank, 1, 1)
        return Prepared(inputs, components, rank, note)

    def encoder(self, architecture: str, in_shape: tuple[int, int, int], dim: int, seeds,
                output_mean: float = 0.0, output_std: float = 1.0) -> BatchedEncoder:
        return BatchedEncoder(architecture, in_shape, dim, seeds, output_mean=output_mean)

    def regulariser(self, z: torch.Tensor) -> torch.Tensor | None:
        """An extra loss term per restart, (R,), from the latents z (R, N, d); None for none."""
        return None


def _times(ratio: float) -> str:
    return "over 1000x" if ratio > 1000 else f"{ratio:.0f}x"


def _th(k: int) -> str:
    return {1: "st", 2: "nd", 3: "rd"}.get(k if k < 20 else k % 10, "th")


class BrightnessObservation(ObservationModel):
    """The camera measures light: the latent is affine in the pixels' linear light.

    Video stores sRGB-encoded values (about I**(1/2.2)); a latent linear in them reads a decay
    rate 2.2 times too slow. This model decodes to linear light first (light="srgb", the default;
    "linear" for frames already proportional to light: raw sensor data, a synthetic rendering),
    then reads the signal subspace with a linear encoder, which can neither bend the latent (an
    MLP could report I**p, decaying at p times the rate) nor draw it out of pixel noise.
    """

    name = "brightness"
    architecture = "linear"

    def applies(self, check: str) -> bool:
        # decoded light is measured too: where the latent slows, the light does (a decay near
        # rest still changes many pixels a little), so it cannot follow only a transient
        return check != "quiet" and super().applies(check)

    def __init__(self, light: str = "srgb", subspace: bool = True):
        super().__init__(subspace)
        if light not in LIGHT_CHOICES:
            raise ConfigError(f"unknown light {light!r}; choose one of {', '.join(LIGHT_CHOICES)}")
        self.light = light

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        out = super().prepare(self.decoded(frames), architecture, fit_frames)
        how = "decoded from sRGB to linear light" if self.light == "srgb" else "read as linear light (light=linear)"
        return replace(out, note=f"pixels {how}; {out.note}")

    def decoded(self, frames: torch.Tensor) -> torch.Tensor:
        if self.light == "linear":
            return frames
        lo, hi = float(frames.min()), float(frames.max())
        if lo < 0 or hi > 255:
            raise ConfigError(f"the brightness observation decodes sRGB pixel values in [0, 1] or 0..255, but these "
                              f"run from {lo:g} to {hi:g}; give light='linear' (--light linear) for other units")
        return srgb_to_linear(frames / 255.0 if hi > 1.0 else frames)


class PositionObservation(ObservationModel):
    """The camera sees where something is: the latent is affine in its image coordinates.

    The heat map is what differs from the clip's median frame (the static scene) by more than
    three times the noise (median absolute deviation) and by more than CORE of the frame's
    largest difference; its centroid moves with the object, exactly for a rigid object in view on
    a static background, whatever its shape, colour or contrast. An object that rests in one
    place for half the clip is part of the median frame: the centroid then mixes where it is
    with where it rests.
    A linear encoder reads the centroid's (x, y): the latent is a position along the line of
    motion, which no encoder can bend (a bend of a parabola is nearly another parabola, with
    another g). For a fall, a slide, a level that drops; a pendulum's latent would be L sin(theta).
    """

    name = "position"
    architecture = "linear"
    geometric = True
    perspective = True

    def encoder(self, architecture: str, in_shape: tuple[int, int, int], dim: int, seeds,
                output_mean: float = 0.0, output_std: float = 1.0) -> BatchedEncoder:
        """The linear read of the unit-variance path, started at weight +-1 (the seed's sign): the
        latent then meets the prior's spread from the first step, which a weight drawn at random
        would leave to an encoder learning rate made for thousands of weights."""
        enc = super().encoder(architecture, in_shape, dim, seeds, output_mean)
        with torch.no_grad():
            w = enc.weights[0]
            w.copy_(torch.where(w >= 0, 1.0, -1.0) * output_std)
        return enc

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        out = super().prepare(frames, architecture, fit_frames)  # the components the checks score against
        xy, pixels, unseen, _ = centroids(frames, fit_frames)
        if unseen > 0.1 * frames.shape[0]:
            raise ConfigError(f"the position observation sees no change from the median frame in {unseen} of "
                              f"{frames.shape[0]} frames (the object stands still or leaves the view); "
                              "trim the clip to the motion (--start/--end) or observe 'any'")
        n_fit = xy.shape[0] if fit_frames is None else int(fit_frames)
        # the line of motion: a linear encoder of two collinear coordinates can cancel its own signal
        direction, path = line_of_motion(xy, n_fit)
        path, mended = mend_one_way(path, n_fit)
        z = path / path[:n_fit].std().clamp_min(1e-6)
        angle = float(torch.rad2deg(torch.atan2(direction[1], direction[0]))) % 180
        note = (f"position: the centroid of what differs most from the static scene ({pixels:.0f} pixels on "
                f"average), along its line of motion ({angle:.0f} degrees from the image's x axis), read linearly")
        caution = None
        if mended:
            note += (f"; {mended} frame{'s' if mended != 1 else ''} whose centroid left the one-way path of "
                     f"{'their' if mended != 1 else 'its'} neighbours read from them")
            if mended > MENDED_MAX * n_fit:
                caution = (f"{mended} of {n_fit} frames had a centroid off the path of their neighbours and were read "
                           "from them: something else changes in the view as much as the object; give --roi around it")
        return Prepared(z.to(frames.dtype).reshape(-1, 1, 1, 1), out.components, 1, note, caution)

    def reread(self, prepared: Prepared, state: np.ndarray, perspective: dict, fit_frames: int) -> Prepared | None:
        """The path read through the camera's perspective that holds.perspective_check found on a
        first training's state (T, 1), which is affine in the path: the encoder's new input is
        that state bent, at unit spread and in the path's orientation. None where a frame lies
        beyond the bend's pole."""
        from .holds import unbend

        bent = unbend(np.asarray(state, dtype=np.float64)[:, 0], perspective["c"], perspective["middle"])
        if bent is None:
            return None
        old = prepared.inputs.reshape(-1).double().cpu().numpy()
        z = (bent - bent[:fit_frames].mean()) / max(float(bent[:fit_frames].std()), 1e-12)
        if float(np.dot(z[:fit_frames], old[:fit_frames])) < 0:
            z = -z
        note = (f"{prepared.note}; read through the camera's perspective: one trajectory of the equation fits "
                f"the whole path {perspective['misfit'][0] / max(perspective['misfit'][1], 1e-300):.1f}x better "
                f"when its ends are bent by {100 * perspective['bend_at_ends']:.1f}% (a camera that looks at the "
                "line of motion at an angle), so it was trained again on the path so corrected")
        inputs = torch.as_tensor(z, dtype=prepared.inputs.dtype, device=prepared.inputs.device).reshape(prepared.inputs.shape)
        return replace(prepared, inputs=inputs, note=note)


class SizeObservation(PositionObservation):
    """The camera sees how large something looks: the latent is affine in its apparent radius
    (train/extent.py), for what grows or shrinks in place (the paper's scale videos, a balloon,
    a spreading drop). Read linearly like a position: no encoder can bend the size into
    another law."""

    name = "size"
    perspective = False  # the distance model is the perspective of a size
    how = "read linearly"

    def reading(self, radius: torch.Tensor) -> torch.Tensor:
        return radius

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        from .extent import SMALL, apparent_radii
        out = ObservationModel.prepare(self, frames, architecture, fit_frames)  # the components the checks score against
        radius, _, unseen = apparent_radii(frames)
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
        return Prepared(z.to(frames.dtype).reshape(-1, 1, 1, 1), out.components, 1, note, caution)


class DistanceObservation(SizeObservation):
    """The camera sees how large something looks as it moves along the line of sight: a pinhole
    camera sees an object of radius R at distance d with radius f R / d, so the latent is affine
    in the reciprocal of the apparent radius (a fall towards or away from the camera: the
    paper's free-fall-scale videos)."""

    name = "distance"
    how = "read as its reciprocal, affine in the distance from the camera"

    def reading(self, radius: torch.Tensor) -> torch.Tensor:
        return 1.0 / radius


CORE = 0.7
MEND_SPAN = 21  # frames around each frame whose running median a one-way path is checked against
MEND_SIGMAS = 6.0
MEND_PIXELS = 1.0
MENDED_MAX = 0.1  # a larger share of mended frames is a finding: the centroid is not the object's


@torch.no_grad()
def centroids(frames: torch.Tensor, fit_frames: int | None = None) -> tuple[torch.Tensor, float, int, torch.Tensor]:
    """(T, 2) image coordinates (x, y) of the centroid of each frame's change from the static
    scene, the mean number of pixels that carry it, how many frames show no change (their
    centroid is the previous frame's), and each frame's largest change (T,).

    The static scene is first the median frame of the first fit_frames; an object that slows
    down (a decay, the end of a slide) sits in that median where it lingers, and its ghost there
    pulls the centroid. So a second pass rebuilds each pixel's background from the frames in
    which the first pass put the object farther away than twice its size, and measures again.
    """
    gray = frames.double().mean(dim=1)  # (T, H, W)
    n_fit = gray.shape[0] if fit_frames is None else int(fit_frames)
    background = gray[:n_fit].median(dim=0).values
    xy, heat = _centroids(gray, background)
    size = float((heat > 0).sum(dim=(1, 2)).double().mean()) ** 0.5
    h, w = gray.shape[1:]
    ys, xs = torch.meshgrid(torch.arange(h, dtype=gray.dtype, device=gray.device),
                            torch.arange(w, dtype=gray.dtype, device=gray.device), indexing="ij")
    far = ((xs[None] - xy[:n_fit, 0, None, None]) ** 2 + (ys[None] - xy[:n_fit, 1, None, None]) ** 2) > (2 * size + 2) ** 2
    count = far.sum(dim=0)
    clean = (gray[:n_fit] * far).sum(dim=0) / count.clamp_min(1)
    background = torch.where(count >= max(3, n_fit // 10), clean, background)
    xy, heat = _centroids(gray, background)
    mass = heat.sum(dim=(1, 2))
    seen = mass > 0
    for t in range(1, len(xy)):  # a frame with no change keeps the last position seen
        if not seen[t]:
            xy[t] = xy[t - 1]
    pixels = float((heat > 0).sum(dim=(1, 2)).double().mean())
    return xy, pixels, int((~seen).sum()), heat.flatten(1).max(dim=1).values


def mend_one_way(path: torch.Tensor, n_fit: int | None = None) -> tuple[torch.Tensor, int]:
    """A path that runs one way (rank correlation with time at least ONE_WAY over the first n_fit
    frames) with the frames that leave it read from their neighbours, and how many those are.

    A one-way path is its own running median (the median of a monotone run is its middle), so
    a frame far from the running median of the MEND_SPAN frames around it is not the object:
    where the change from the static scene is a boundary (a water level), it vanishes as the
    level passes its median place, and the centroid of whatever else changes then (the jet under
    the bottle) is taken for a few frames. Far means more than MEND_SIGMAS times the residuals'
    robust spread and more than MEND_PIXELS. The ends are extended by point reflection, which
    keeps a steady run steady. A path that turns back (an oscillation) is left as it is."""
    n = path.shape[0]
    n_fit = n if n_fit is None else int(n_fit)
    if n_fit < 8:
        return path, 0
    if one_way(path[:n_fit]) < ONE_WAY:
        return path, 0
    x = path.double().cpu().numpy()
    half = max(2, min(MEND_SPAN // 2, n // 4))
    mended, off = x, np.zeros(n, dtype=bool)
    for _ in range(2):  # the second round against the mended path: the first's median leans towards a run of strays
        padded = np.concatenate([2 * mended[0] - mended[half:0:-1], mended,
                                 2 * mended[-1] - mended[-2:-half - 2:-1]])
        residual = x - np.median(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1), axis=1)
        spread = float(_noise(torch.from_numpy(np.abs(residual))))
        off = np.abs(residual) > max(MEND_SIGMAS * spread, MEND_PIXELS)
        if not off.any() or off.all():
            return path, 0
        good = np.flatnonzero(~off)
        mended = x.copy()
        mended[off] = np.interp(np.flatnonzero(off), good, x[good])
    return torch.as_tensor(mended, dtype=path.dtype, device=path.device), int(off.sum())


def one_way(path: torch.Tensor) -> float:
    """How one way a path (T,) runs in time: the absolute rank correlation of its values with
    their frame numbers (1: monotone; about 0: back and forth)."""
    ranks = torch.argsort(torch.argsort(path)).double()
    t = torch.arange(len(ranks), dtype=torch.float64, device=ranks.device)
    return abs(float(torch.corrcoef(torch.stack([ranks, t]))[0, 1]))


def line_of_motion(xy: torch.Tensor, n_fit: int | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """The direction (2,) along which the centroids of the first n_fit frames spread most, and
    every centroid's signed distance along it from their mean, (T,)."""
    n_fit = xy.shape[0] if n_fit is None else n_fit
    centred = xy - xy[:n_fit].mean(dim=0)
    direction = torch.linalg.svd(centred[:n_fit], full_matrices=False).Vh[0]
    return direction, centred @ direction


def _noise(diff: torch.Tensor) -> torch.Tensor:
    """The noise level of differences from the static scene: their median absolute value, scaled
    to a standard deviation (most pixels of most frames show only noise)."""
    return 1.4826 * diff.flatten().median() + 1e-12


def _centroids(gray: torch.Tensor, background: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    diff = (gray - background).abs()
    noise = _noise(diff)
    # only each frame's strongest change: the object, not a hand that moves at the edge, a
    # shadow or the camera's exposure drifting over the whole wall
    floor = torch.maximum(3 * noise, CORE * diff.flatten(1).max(dim=1).values)[:, None, None]
    heat = _strongest_region(torch.where(diff > floor, diff, torch.zeros_like(diff)))
    mass = heat.sum(dim=(1, 2)).clamp_min(1e-12)
    h, w = gray.shape[1:]
    ys = torch.arange(h, dtype=heat.dtype, device=heat.device)
    xs = torch.arange(w, dtype=heat.dtype, device=heat.device)
    cx = (heat.sum(dim=1) * xs).sum(dim=1) / mass
    cy = (heat.sum(dim=2) * ys).sum(dim=1) / mass
    return torch.stack([cx, cy], dim=1), heat


def _strongest_region(heat: torch.Tensor) -> torch.Tensor:
    """Each frame's heat (T, H, W) cut to its connected region of largest total change (pixels
    one apart count as connected): a hand that pulls back at the frame's edge while a fading,
    motion-blurred ball crosses the middle passes the threshold too, and the centroid of both
    lies between them, where nothing is."""
    import cv2

    kept = heat.clone()
    near = np.ones((3, 3), np.uint8)
    for t, frame in enumerate(heat.cpu().numpy()):
        mask = cv2.dilate((frame > 0).astype(np.uint8), near)
        n, labels = cv2.connectedComponents(mask, connectivity=8)
        if n <= 2:  # one region, or none
            continue
        mass = np.bincount(labels.ravel(), weights=frame.ravel(), minlength=n)
        mass[0] = 0.0
        kept[t] = torch.where(torch.from_numpy(labels == int(np.argmax(mass))).to(heat.device), heat[t], 0.0)
    return kept


OBSERVATIONS = {"any": ObservationModel, "brightness": BrightnessObservation, "position": PositionObservation,
                "size": SizeObservation, "distance": DistanceObservation}
assert ("auto",) + tuple(OBSERVATIONS) == OBSERVE_CHOICES, "train/config.py lists the models the CLI offers"

# The auto choice looks at where the frames change (the heat map of PositionObservation): a
# change whose centroid travels farther than the changing region's own size is something that
# moves; one that moves ONE_WAY (|rank correlation| of its travel with time) is a fall, a slide
# or a level that drops; a change that stays in place is light.
ONE_WAY = 0.9
STRONG = 0.25  # frames whose largest change is at least this share of the clip's largest
LOOK_FRAMES = 256


def resolve_observation(spec: str | ObservationModel | None, system, frames: torch.Tensor | None = None,
                        light: str = "srgb", encoder: str = "auto", source: str = "as asked") -> ObservationModel:
    """The observation model a fit uses, with its reason: an instance as given, a name, or "auto"
    (None): position where the change moves one way, brightness for a single first-order linear
    equation whose frames brighten or dim as one, any otherwise (and wherever an encoder other
    than linear was asked for). source: where a named model came from, for its reason."""
    if isinstance(spec, ObservationModel):
        spec.reason = spec.reason or f"{spec.name} (as given)"
        return spec
    name = "auto" if spec is None else spec
    if name not in OBSERVE_CHOICES:
        raise ConfigError(f"unknown observation model {name!r}; choose one of {', '.join(OBSERVE_CHOICES)}")
    if name != "auto":
        model = BrightnessObservation(light) if name == "brightness" else OBSERVATIONS[name]()
        model.reason = f"{name} ({source})"
        return model
    if encoder not in ("auto", "linear"):
        model = ObservationModel()
        model.reason = f"any (auto: the {encoder} encoder was asked for)"
        return model
    from fitode.eqparse.identify import power_symmetric  # sympy: only when a fit is set up
    seen = look(frames) if frames is not None else None
    if seen is not None and seen.moves and seen.one_way >= ONE_WAY:
        model = PositionObservation()
        model.reason = (f"position (auto: the change moves {seen.travel:.0f} pixels, {seen.travel / seen.size:.0f}x its "
                        f"size, one way (rank correlation {seen.one_way:.2f} with time): a free encoder could bend "
                        "its path into one with other constants)")
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


@dataclass
class Look:
    """Where the frames change: how far the change's centroid travels, the changing region's size
    (the square root of its area), both in pixels, and how one-way the travel runs in time."""

    travel: float
    size: float
    one_way: float
    gap: float = 1.0  # the frames' first singular value over their second

    @property
    def moves(self) -> bool:
        """The change travels farther than its size, and it is not one pattern that brightens
        and dims: a lamp's frames lie on one line in pixel space (a clear gap after the first
        singular value), even where its brightest core seems to wander."""
        return self.travel > self.size and self.gap < SUBSPACE_JUMP


@torch.no_grad()
def look(frames: torch.Tensor) -> Look:
    """The look behind the auto choice, from at most LOOK_FRAMES frames spread over the clip."""
    sub = frames[:: max(1, frames.shape[0] // LOOK_FRAMES)]
    xy, _, _, peak = centroids(sub)
    # frames that barely differ from the static scene (a lamp at its median brightness) have a
    # centroid of noise: only the frames with a clear change say where it is
    strong = peak >= STRONG * peak.max()
    xy = xy[strong]
    # the size of everything that changes (a lamp's whole glow, not only its brightest core)
    gray = sub.double().mean(dim=1)
    diff = (gray - gray.median(dim=0).values).abs()
    pixels = float((diff[strong] > 3 * _noise(diff)).sum(dim=(1, 2)).double().mean()) if bool(strong.any()) else 0.0
    flat = gray.reshape(gray.shape[0], -1)
    flat = flat - flat.mean(dim=0)
    sv = torch.linalg.eigvalsh(flat @ flat.T).flip(0).clamp_min(0).sqrt()
    gap = float(sv[0] / sv[1].clamp_min(1e-12)) if len(sv) > 1 else 1.0
    if xy.shape[0] < 3 or float((xy - xy.mean(dim=0)).abs().max()) == 0:
        return Look(0.0, max(pixels, 1.0) ** 0.5, 0.0, gap)
    _, path = line_of_motion(xy)
    return Look(float(path.max() - path.min()), max(pixels, 1.0) ** 0.5, one_way(path), gap)
