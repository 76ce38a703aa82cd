"""The position observation: the latent is affine in where something is along its line of motion."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from fitode.errors import ConfigError

from .base import MeasuredObservation, ObservationModel, Prepared
from .drawing import points, record
from .tracking import MENDED_MAX, centroids, line_of_motion, mend_one_way


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
    """

    name = "position"

    def applies(self, check: str) -> bool:
        return True if check == "perspective" else super().applies(check)

    def prepare(self, frames: torch.Tensor, architecture: str = "linear", fit_frames: int | None = None) -> Prepared:
        out = ObservationModel.prepare(self, frames, architecture, fit_frames)  # the components the checks score against
        xy, pixels, unseen, _ = centroids(frames, fit_frames)
        if unseen > 0.1 * frames.shape[0]:
            raise ConfigError(f"the position observation sees no change from the median frame in {unseen} of "
                              f"{frames.shape[0]} frames (the object stands still or leaves the view); "
                              "trim the clip to the motion (--start/--end) or observe 'any'")
        n_fit = xy.shape[0] if fit_frames is None else int(fit_frames)
        # the line of motion: a linear encoder of two collinear coordinates can cancel its own signal
        direction, raw = line_of_motion(xy, n_fit)
        path, mended = mend_one_way(raw, n_fit)
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
        drawing = record(self.name, reading="line", track=points(xy),
                         mended=[int(i) for i in torch.nonzero(path != raw).flatten()] if mended else None,
                         line={"point": [float(v) for v in xy[:n_fit].mean(dim=0)],
                               "direction": [float(v) for v in direction]})
        return self.column(z.to(frames.dtype), out.components, note, caution, drawing)

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
        note = (f"{prepared.note}; read through the camera's perspective: one trajectory of the equation fits "
                f"the whole path {perspective['misfit'][0] / max(perspective['misfit'][1], 1e-300):.1f}x better "
                f"when its ends are bent by {100 * perspective['bend_at_ends']:.1f}% (a camera that looks at the "
                "line of motion at an angle), so it was trained again on the path so corrected")
        inputs = torch.as_tensor(z, dtype=prepared.inputs.dtype, device=prepared.inputs.device).reshape(prepared.inputs.shape)
        return replace(prepared, inputs=inputs, note=note)
