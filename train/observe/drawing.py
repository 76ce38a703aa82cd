"""What an observation model measured, as a record to draw on the frames (Prepared.drawing).

The record is plain data (lists, numbers, strings) so that it goes into result.json as it is. Its
keys (all optional but "kind"): "track" [[x, y] or None per frame], "mended" [frames whose point left
the path of their neighbours and was read from them], "line" {"point", "direction"},
"region" [x0, y0, x1, y1], "radii" [r per frame], "pivot" [x, y], "radius" r, "states"
{state: reading}. A model that measures on the frames it was given says so with
"space": "frames": its coordinates are pixel centres of those frames (x right, y down), which
fitode.measurement maps to the source video's pixels where it knows the crop and the resize.
"""
from __future__ import annotations

from typing import Any

import torch

REGION_CORE = 0.3  # a pixel belongs to the region that changes where its spread over time reaches this share of the largest


def region_of_change(frames: torch.Tensor, fit_frames: int | None = None) -> list[float] | None:
    """[x0, y0, x1, y1] (pixel edges, in the frames' pixels) around the pixels whose values spread
    over time by at least REGION_CORE of the largest spread: where the light changes, or where the
    frames change at all. None where nothing changes."""
    n_fit = frames.shape[0] if fit_frames is None else int(fit_frames)
    spread = frames[:n_fit].double().std(dim=0).mean(dim=0)  # (H, W)
    top = float(spread.max()) if spread.numel() else 0.0
    if not top > 0:
        return None
    ys, xs = torch.nonzero(spread >= REGION_CORE * top, as_tuple=True)
    return [float(xs.min()) - 0.5, float(ys.min()) - 0.5, float(xs.max()) + 0.5, float(ys.max()) + 0.5]


def points(xy: torch.Tensor) -> list[list[float]]:
    """(T, 2) coordinates as a list of [x, y]."""
    return [[float(x), float(y)] for x, y in xy.double().cpu().tolist()]


def record(kind: str, **keys: Any) -> dict[str, Any]:
    """A drawing in the given frames' pixels, without the keys left None."""
    return {"kind": kind, "space": "frames", **{k: v for k, v in keys.items() if v is not None}}
