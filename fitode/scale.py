"""A scale stick: two points of the source frame and the distance between them, as Tracker's
calibration stick. With one, a measured position, level or size is in metres (y up), and every
constant built from it in SI units; its uncertainty goes into each constant's interval.

    --scale "X1,Y1,X2,Y2=D"        source pixels (x right, y down, as --roi), D in metres
    --scale "X1,Y1,X2,Y2=D±U"      U: the distance's standard deviation (or D+-U)
    --scale "X1,Y1,X2,Y2±P=D"      P: each end's standard deviation in pixels (1 unless said)
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from fitode.errors import ConfigError
from fitode.names import finite_number

END_STD = 1.0  # a point clicked on a ruler's mark is off by about a pixel along each axis
_PLUS_MINUS = re.compile(r"\s*(?:±|\+-|\+/-)\s*")


@dataclass(frozen=True)
class ScaleStick:
    """Two source pixels (x right, y down) a known distance apart, in metres."""

    p1: tuple[float, float]
    p2: tuple[float, float]
    distance: float
    distance_std: float = 0.0
    end_std: float = END_STD

    @property
    def pixels(self) -> float:
        return math.dist(self.p1, self.p2)

    @property
    def metres_per_px(self) -> float:
        return self.distance / self.pixels

    @property
    def relative_std(self) -> float:
        """The relative standard deviation of metres per pixel: the distance's, and the two ends'
        (each end's error along the stick adds to the length in pixels)."""
        return math.hypot(self.distance_std / self.distance, math.sqrt(2.0) * self.end_std / self.pixels)

    def check_inside(self, source_size: tuple[int, int]) -> None:
        """Both ends within the source frame (width, height)."""
        w, h = source_size
        for x, y in (self.p1, self.p2):
            if not (-0.5 <= x <= w - 0.5 and -0.5 <= y <= h - 0.5):
                raise ConfigError(f"--scale: the point ({x:g}, {y:g}) lies outside the source frame, {w}x{h} pixels "
                                  "(x right, y down, from 0)")

    def describe(self) -> str:
        return (f"({self.p1[0]:g}, {self.p1[1]:g}) to ({self.p2[0]:g}, {self.p2[1]:g}) is {self.distance:g} m"
                + (f" ± {self.distance_std:g}" if self.distance_std else "")
                + f" over {self.pixels:.1f} source pixels: {1000 * self.metres_per_px:.5g} mm per pixel "
                f"(±{100 * self.relative_std:.2g}%, each end ±{self.end_std:g} px)")

    def to_dict(self) -> dict[str, Any]:
        return {"p1": list(self.p1), "p2": list(self.p2), "distance": self.distance,
                "distance_std": self.distance_std, "end_std": self.end_std,
                "metres_per_px": self.metres_per_px, "relative_std": self.relative_std}


def parse_scale(value) -> ScaleStick:
    """--scale's text, or the API's ((x1, y1), (x2, y2), D) with D a number, (D, U) or "D±U"."""
    if isinstance(value, ScaleStick):
        return value
    if isinstance(value, str):
        head, eq, tail = value.partition("=")
        if not eq:
            raise ConfigError(f"--scale: cannot read {value!r}; write X1,Y1,X2,Y2=D (source pixels, x right, y down; "
                              "D in metres, D±U with its uncertainty)")
        head, _, end = _PLUS_MINUS.sub("\0", head).partition("\0")
        parts = [p for p in head.split(",")]
        if len(parts) != 4:
            raise ConfigError(f"--scale: {head.strip()!r} has {len(parts)} numbers; give the two ends as X1,Y1,X2,Y2")
        xs = [_number(p, "a coordinate") for p in parts]
        points = ((xs[0], xs[1]), (xs[2], xs[3]))
        distance = tail
        end_std = _number(end, "each end's uncertainty") if end.strip() else END_STD
    else:
        try:
            p1, p2, distance = value
            points = ((_number(p1[0], "a coordinate"), _number(p1[1], "a coordinate")),
                      (_number(p2[0], "a coordinate"), _number(p2[1], "a coordinate")))
        except (TypeError, ValueError, IndexError):
            raise ConfigError(f"scale must be ((x1, y1), (x2, y2), D), got {value!r}") from None
        end_std = END_STD
    d, sd = _distance(distance)
    if d <= 0:
        raise ConfigError(f"--scale: the distance must be positive, got {d:g}")
    if sd < 0 or end_std < 0:
        raise ConfigError("--scale: an uncertainty must not be negative")
    if math.dist(*points) < 1.0:
        raise ConfigError("--scale: the two ends are less than a pixel apart; give two marks far apart")
    return ScaleStick(points[0], points[1], d, sd, end_std)


def _distance(value) -> tuple[float, float]:
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return _number(value[0], "the distance"), _number(value[1], "the distance's uncertainty")
    if isinstance(value, str):
        d, _, u = _PLUS_MINUS.sub("\0", value).partition("\0")
        return _number(d, "the distance"), (_number(u, "the distance's uncertainty") if u.strip() else 0.0)
    return _number(value, "the distance"), 0.0


def _number(text, what: str) -> float:
    if isinstance(text, bool):
        raise ConfigError(f"--scale: {what} is not a number: {text!r}")
    if isinstance(text, (int, float)):
        text = repr(float(text))
    shown = str(text).strip()
    return finite_number(shown, f"--scale: {what} is not a number: {shown!r}", f"--scale: {what} is not finite",
                         ConfigError)
