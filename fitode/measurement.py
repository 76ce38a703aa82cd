"""The measurement record (FitResult.meta["measurement"], result.json "measurement") in the
source video's pixels.

An observation model measures on the frames it is given, which the reader cropped (--roi) and
shrank; its record says so with "space": "frames" (fitode.train.observe.drawing). The reader
knows the crop and the resize, so the record is mapped here, once, to the source's pixels (x
right, y down, pixel centres at whole numbers), and says "space": "source" with the source's
size and the crop. A record already in source pixels (a full-resolution tracker's) is kept.
"""
from __future__ import annotations

import math

from dataclasses import dataclass
from typing import Any, Mapping


@dataclass(frozen=True)
class FrameGeometry:
    """Where the frames a model measured lie in the source: the crop box (x, y, w, h) in source
    pixels that was resized to frame_size (W, H), and the source's size (W, H)."""

    box: tuple[int, int, int, int]
    frame_size: tuple[int, int]
    source_size: tuple[int, int]

    @property
    def scale(self) -> tuple[float, float]:
        """Source pixels per frame pixel, along x and y."""
        return self.box[2] / self.frame_size[0], self.box[3] / self.frame_size[1]

    def point(self, p) -> list[float] | None:
        """A frame pixel's coordinates (x, y) -> the source's; a pixel's centre maps to the centre
        of the source pixels it averages."""
        if p is None:
            return None
        sx, sy = self.scale
        return [self.box[0] + (float(p[0]) + 0.5) * sx - 0.5, self.box[1] + (float(p[1]) + 0.5) * sy - 0.5]


def geometry(clip) -> FrameGeometry:
    """The geometry of a fitode.video.Clip: its crop as the reader cut it (Preprocess.box: the
    --roi, or the whole frame, less the few rows a whole-number shrink drops)."""
    from fitode.video.preprocess import Preprocess

    h, w = clip.source_size
    crop = clip.roi or (0, 0, w, h)
    fh, fw = clip.size
    box = Preprocess(tuple(int(v) for v in crop), (fh, fw), False, "BGR").box
    return FrameGeometry(tuple(int(v) for v in box), (fw, fh), (int(w), int(h)))


def in_source_pixels(drawing: Mapping[str, Any] | None, geo: FrameGeometry) -> dict[str, Any] | None:
    """A record in the frames' pixels mapped to the source's (see the module docstring)."""
    if drawing is None:
        return None
    out = dict(drawing)
    if out.get("space", "frames") == "frames":
        sx, sy = geo.scale
        mean = 0.5 * (sx + sy)
        if out.get("track") is not None:
            out["track"] = [geo.point(p) for p in out["track"]]
        for key in ("pivot",):
            if out.get(key) is not None:
                out[key] = geo.point(out[key])
        if out.get("line"):
            dx, dy = out["line"]["direction"]
            norm = ((dx * sx) ** 2 + (dy * sy) ** 2) ** 0.5 or 1.0
            out["line"] = {"point": geo.point(out["line"]["point"]), "direction": [dx * sx / norm, dy * sy / norm]}
        if out.get("region"):
            x0, y0, x1, y1 = out["region"]
            out["region"] = geo.point((x0, y0)) + geo.point((x1, y1))
        if out.get("radius") is not None:
            out["radius"] = float(out["radius"]) * mean
        if out.get("radii") is not None:
            out["radii"] = [None if r is None else float(r) * mean for r in out["radii"]]
        out["space"] = "source"
    out.setdefault("source_size", list(geo.source_size))
    out.setdefault("crop", list(geo.box))
    return out


@dataclass
class Reading:
    """One state's measured reading over the clip in the image's units (pixels, degrees), and the
    equation's fitted trajectory read the same way.

    measured, fitted: (T,) with NaN where nothing was seen or the trajectory left the finite range;
    points: (T, 2) the fitted trajectory as image points (source pixels) where the reading is a place
    (along a line, an angle about a pivot), else None; label: the axis label; latent_map: (a, b) with
    reading = a * latent + b where the reading is affine in the latent (NaN where it is not)."""

    state: str
    label: str
    measured: "np.ndarray"
    fitted: "np.ndarray"
    points: "np.ndarray | None" = None
    latent_map: tuple[float, float] = (float("nan"), float("nan"))


def readings(measurement: Mapping[str, Any] | None, latent, rollout, states) -> list[Reading]:
    """The readings of the states the record measured, with the fitted trajectory (rollout, the
    latent's units) mapped to the reading's units by the affine map that takes the latent to the
    measured reading (least squares over the frames where both are finite): the latent of a
    measured model is affine in what it measured, whatever scale and offset the encoder chose."""
    import numpy as np

    if not measurement:
        return []
    z = np.asarray(latent, dtype=float).reshape(len(latent), -1)
    r = np.asarray(rollout, dtype=float).reshape(len(latent), -1)
    track = _track(measurement, len(z))
    out = []
    for state, how in (measurement.get("states") or {}).items():
        if state not in states:
            continue
        j = list(states).index(state)
        got = _measured(measurement, how, track, len(z))
        if got is None:
            continue
        measured, label, to_reading, to_points = got
        # (not over the frames the latent read from their neighbours: the track there is what
        # the reader set aside, a block gone from the view, and pulled the trajectory off the path)
        mended = [i for i in (measurement.get("mended") or ()) if 0 <= int(i) < len(z)]
        kept = z[:, j].copy()
        kept[mended] = np.nan
        a, b = _affine(kept, to_reading(measured, inverse=True))
        if how == "line" and a < 0:  # along the line the way the state grows: a fall reads as a distance fallen
            m = {**measurement, "line": {**measurement["line"], "direction": [-v for v in measurement["line"]["direction"]]}}
            measured, label, to_reading, to_points = _measured(m, how, track, len(z))
            a, b = -a, -b
        with np.errstate(all="ignore"):
            fitted = to_reading(a * r[:, j] + b, inverse=False)
        fitted[~np.isfinite(fitted)] = np.nan
        affine = (a, b) if how in ("line", "radius", "angle", "level") else (float("nan"), float("nan"))
        out.append(Reading(state, label, measured, fitted, to_points(fitted) if to_points else None, affine))
    return out


def _track(measurement: Mapping[str, Any], n: int):
    import numpy as np

    xy = np.full((n, 2), np.nan)
    for i, p in enumerate((measurement.get("track") or [])[:n]):
        if p is not None:
            xy[i] = p
    return xy


def _measured(m: Mapping[str, Any], how: str, track, n: int):
    """(measured (T,), axis label, reading <-> what the latent is affine in, fitted points) for
    one reading, or None where the record has no series for it."""
    import numpy as np

    same = lambda v, inverse: np.asarray(v, dtype=float)  # noqa: E731 - the latent is affine in the reading itself
    if how == "line" and m.get("line"):
        p0, d = np.asarray(m["line"]["point"], float), np.asarray(m["line"]["direction"], float)
        along = (track - p0) @ d
        return (along, "position along the line of motion\n(pixels of the source video)", same,
                lambda v: p0 + np.asarray(v)[:, None] * d)
    if how in ("radius", "1/radius") and m.get("radii"):
        radii = np.array([np.nan if v is None else v for v in m["radii"][:n]], dtype=float)
        if how == "radius":
            return radii, "apparent radius\n(pixels of the source video)", same, None
        flip = lambda v, inverse: 1.0 / np.asarray(v, dtype=float)  # noqa: E731 - the latent is affine in 1/radius
        return radii, "apparent radius\n(pixels of the source video)", flip, None
    if how == "level" and m.get("levels"):
        levels = np.array([np.nan if v is None else v for v in m["levels"][:n]], dtype=float)
        return levels, "height of the water line\n(rows of the frames fitted, up)", same, None
    if how in ("x", "y"):  # a state read along the image axis its name says (train/observe/position.py)
        column, sign = (0, 1.0) if how == "x" else (1, -1.0)  # y up: the image's rows grow down

        def on_axis(v):  # the fitted coordinate where the tracked point is on the other axis
            points = track.copy()
            points[:, column] = sign * np.asarray(v, dtype=float)
            return points
        label = "across" if how == "x" else "height, up"
        return sign * track[:, column], f"{label}\n(pixels of the source video)", same, on_axis
    if how == "angle" and m.get("pivot") is not None:
        pivot = np.asarray(m["pivot"], float)
        radius = float(m.get("radius") or np.nanmedian(np.hypot(*(track - pivot).T)))
        # the fit's own angle (fitode.train.observe.angle.angles), so that track.png shows the sign and zero
        # of latent.png and track.csv: from the direction it hangs in, growing clockwise on screen (image
        # axes, y down); a record without that direction hangs straight down
        hang = float(m["hanging"]) if m.get("hanging") is not None else math.pi / 2
        raw = np.arctan2(track[:, 1] - pivot[1], track[:, 0] - pivot[0]) - hang
        degrees = np.degrees((raw + math.pi) % (2 * math.pi) - math.pi)
        return (degrees, "angle from where it hangs (degrees;\nas the fit's: clockwise on screen)", same,
                lambda v: pivot + radius * np.stack([np.cos(hang + np.radians(v)), np.sin(hang + np.radians(v))], axis=1))
    return None


def _affine(z, y) -> tuple[float, float]:
    import numpy as np

    ok = np.isfinite(z) & np.isfinite(y)
    if ok.sum() < 2 or np.ptp(z[ok]) == 0:
        return float("nan"), float("nan")
    a, b = np.polyfit(z[ok], y[ok], 1)
    return float(a), float(b)
