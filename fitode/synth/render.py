"""Anti-aliased drawing shared by every generator.

Shapes are signed distance functions (negative inside) in continuous output-pixel
coordinates: x to the right, y down, pixel (row r, column c) covers [c, c+1) x [r, r+1), so
the centre of a W x H frame is (W/2, H/2). A shape is drawn by evaluating its distance on a
grid `ss` times finer than the output (ss^2 samples per pixel), turning the distance into a
sub-sample coverage ramp one sub-sample wide, and area-averaging back to the output grid.
Supersampling makes a pixel's value the fraction of it the shape covers, so a sub-pixel
move of an edge changes the frame; the ramp removes what staircase is left at ss = 4.

Only the bounding box of a shape is evaluated, so small objects on large realistic frames
cost little.
"""
from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

Sdf = Callable[[np.ndarray, np.ndarray], np.ndarray]
Color = float | tuple[float, ...] | np.ndarray | Callable[[np.ndarray, np.ndarray], np.ndarray]


# --- signed distance functions ---------------------------------------------------------

def circle(cx: float, cy: float, r: float) -> Sdf:
    return lambda x, y: np.hypot(x - cx, y - cy) - r


def segment(ax: float, ay: float, bx: float, by: float, half_width: float) -> Sdf:
    """A capsule: all points within half_width of the segment a-b."""
    dx, dy = bx - ax, by - ay
    den = dx * dx + dy * dy

    def sdf(x, y):
        px, py = x - ax, y - ay
        h = np.clip((px * dx + py * dy) / den, 0.0, 1.0) if den > 0 else 0.0
        return np.hypot(px - h * dx, py - h * dy) - half_width
    return sdf


def box(cx: float, cy: float, half_w: float, half_h: float, angle: float = 0.0,
        radius: float = 0.0) -> Sdf:
    """A rectangle centred at (cx, cy), rotated by `angle` radians (clockwise on screen, as
    y points down), with corners rounded by `radius`."""
    c, s = np.cos(angle), np.sin(angle)
    hw, hh = half_w - radius, half_h - radius

    def sdf(x, y):
        px, py = x - cx, y - cy
        u, v = c * px + s * py, -s * px + c * py
        qx, qy = np.abs(u) - hw, np.abs(v) - hh
        outside = np.hypot(np.maximum(qx, 0), np.maximum(qy, 0))
        return outside + np.minimum(np.maximum(qx, qy), 0) - radius
    return sdf


def half_plane(nx: float, ny: float, px: float, py: float) -> Sdf:
    """Points on the side of the line through (px, py) opposite to the normal (nx, ny)."""
    n = np.hypot(nx, ny)
    nx, ny = nx / n, ny / n
    return lambda x, y: (x - px) * nx + (y - py) * ny


def polygon(points: np.ndarray) -> Sdf:
    """Exact signed distance to a simple polygon given as (N, 2) vertices (x, y)."""
    pts = np.asarray(points, dtype=np.float64)

    def sdf(x, y):
        d = np.full(x.shape, np.inf)
        inside = np.zeros(x.shape, dtype=bool)
        n = len(pts)
        for i in range(n):
            ax, ay = pts[i - 1]
            bx, by = pts[i]
            ex, ey = bx - ax, by - ay
            wx, wy = x - ax, y - ay
            h = np.clip((wx * ex + wy * ey) / (ex * ex + ey * ey), 0, 1)
            d = np.minimum(d, np.hypot(wx - h * ex, wy - h * ey))
            # even-odd crossing test for the sign
            cond = (ay > y) != (by > y)
            xint = ax + (y - ay) * ex / np.where(ey == 0, 1, ey)
            inside ^= cond & (x < xint)
        return np.where(inside, -d, d)
    return sdf


def star_blob(cx: float, cy: float, radius: float, amps: np.ndarray, phases: np.ndarray) -> Sdf:
    """A smooth irregular star-shaped blob: r(phi) = radius * (1 + sum_k a_k cos(k phi + p_k)),
    k = 2, 3, ... The distance is the radial gap divided by the boundary's slope factor, exact
    to first order near the edge, which is all the coverage ramp needs."""
    ks = np.arange(2, 2 + len(amps))

    def sdf(x, y):
        dx, dy = x - cx, y - cy
        rho = np.hypot(dx, dy)
        phi = np.arctan2(dy, dx)
        arg = ks[:, None, None] * phi[None] + phases[:, None, None]
        r = radius * (1 + np.tensordot(amps, np.cos(arg), axes=1))
        dr = radius * np.tensordot(-amps * ks, np.sin(arg), axes=1)
        return (rho - r) / np.sqrt(1 + (dr / np.maximum(r, 1e-6)) ** 2)
    return sdf


def hand(cx: float, cy: float, size: float, angle: float = 0.0) -> Sdf:
    """A hand-like blob: a palm of `size` pixels across at (cx, cy) and four fingers and a thumb
    reaching out along `angle` (radians, clockwise on screen), as a hand that pinches something
    at (cx, cy) + 0.9 size (cos angle, sin angle) would be drawn at this scale."""
    c, s = np.cos(angle), np.sin(angle)
    palm = box(cx, cy, 0.5 * size, 0.42 * size, angle, radius=0.2 * size)
    parts = [palm]
    for k, (along, across, length) in enumerate(((0.45, -0.3, 0.45), (0.5, -0.1, 0.5), (0.5, 0.1, 0.48),
                                                 (0.45, 0.28, 0.4))):
        ax, ay = cx + along * size * c - across * size * s, cy + along * size * s + across * size * c
        parts.append(segment(ax, ay, ax + length * size * c, ay + length * size * s, 0.09 * size))
    tx, ty = cx + 0.2 * size * c + 0.4 * size * s, cy + 0.2 * size * s - 0.4 * size * c
    parts.append(segment(tx, ty, tx + 0.45 * size * c + 0.1 * size * s, ty + 0.45 * size * s - 0.1 * size * c,
                         0.1 * size))
    return union(*parts)


def scale_marks(canvas: "Canvas", a: tuple[float, float], b: tuple[float, float], size: float = 4.0) -> None:
    """Two dark cross-hair marks (tape on a wall, a ruler's ends) at the pixel points a and b, the
    reference a user measures a scale from."""
    for x, y in (a, b):
        bbox = (x - size - 2, y - size - 2, x + size + 2, y + size + 2)
        canvas.paint(union(segment(x - size, y, x + size, y, 0.6), segment(x, y - size, x, y + size, 0.6)),
                     0.05, bbox)


def union(*sdfs: Sdf) -> Sdf:
    return lambda x, y: np.minimum.reduce([f(x, y) for f in sdfs])


def intersect(*sdfs: Sdf) -> Sdf:
    return lambda x, y: np.maximum.reduce([f(x, y) for f in sdfs])


# --- rasterisation ---------------------------------------------------------------------

def pixel_centres(x0: int, y0: int, w: int, h: int, ss: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Sample positions of a (h*ss, w*ss) grid covering output pixels [x0, x0+w) x [y0, y0+h)."""
    xs = x0 + (np.arange(w * ss) + 0.5) / ss
    ys = y0 + (np.arange(h * ss) + 0.5) / ss
    return np.meshgrid(xs, ys)


def area_downsample(a: np.ndarray, ss: int) -> np.ndarray:
    if ss == 1:
        return a
    h, w = a.shape[0] // ss, a.shape[1] // ss
    return a.reshape(h, ss, w, ss, *a.shape[2:]).mean(axis=(1, 3))


def coverage(sdf: Sdf, x0: int, y0: int, w: int, h: int, ss: int, soft: float = 0.0) -> np.ndarray:
    """Fraction of each output pixel inside the shape (float32, (h, w)).

    soft > 0 widens the edge ramp to `soft` output pixels (a blurred edge: shadows, glows).

    The distance is first taken at pixel centres: a pixel whose centre is farther than half
    its diagonal plus half the ramp from the edge is wholly in or out, so only the band of
    edge pixels is supersampled. That holds for exact distances and for the bounds that
    union/intersect give (and with a margin for star_blob's first-order distance)."""
    ramp = max(1.0 / ss, soft)
    xc, yc = pixel_centres(x0, y0, w, h, 1)
    d1 = sdf(xc, yc)
    a = (d1 < 0).astype(np.float32)
    if ss == 1 and soft <= 1.0:
        return np.clip(0.5 - d1 / ramp, 0.0, 1.0).astype(np.float32)
    edge = np.abs(d1) < 0.75 + ramp / 2 + 0.25
    if not edge.any():
        return a
    rows, cols = np.nonzero(edge)
    off = (np.arange(ss) + 0.5) / ss - 0.5
    ox, oy = np.meshgrid(off, off)
    xs = xc[rows, cols][:, None] + ox.reshape(1, -1)
    ys = yc[rows, cols][:, None] + oy.reshape(1, -1)
    d = sdf(xs, ys)
    a[rows, cols] = np.clip(0.5 - d / ramp, 0.0, 1.0).mean(axis=1)
    return a


class Canvas:
    """An image (float32, (H, W) or (H, W, C), values in [0, 1]) that shapes are painted on."""

    def __init__(self, image: np.ndarray, ss: int = 4):
        self.image = np.ascontiguousarray(image, dtype=np.float32)
        self.ss = int(ss)

    @property
    def height(self) -> int:
        return self.image.shape[0]

    @property
    def width(self) -> int:
        return self.image.shape[1]

    def _box(self, bbox: tuple[float, float, float, float] | None) -> tuple[int, int, int, int] | None:
        if bbox is None:
            return 0, 0, self.width, self.height
        x0 = max(int(np.floor(bbox[0])) - 1, 0)
        y0 = max(int(np.floor(bbox[1])) - 1, 0)
        x1 = min(int(np.ceil(bbox[2])) + 1, self.width)
        y1 = min(int(np.ceil(bbox[3])) + 1, self.height)
        if x1 <= x0 or y1 <= y0:
            return None
        return x0, y0, x1 - x0, y1 - y0

    def paint(self, sdf: Sdf, color: Color, bbox: tuple[float, float, float, float] | None = None,
              opacity: float = 1.0, soft: float = 0.0) -> np.ndarray | None:
        """Paint a shape over the image; bbox = (x_min, y_min, x_max, y_max) bounds the shape.

        color: a gray level, a per-channel tuple, or a function of the pixel-centre
        coordinates (x, y) giving (h, w) or (h, w, C) values (shading, texture).
        Returns the coverage that was used (or None when the shape is off the canvas)."""
        b = self._box(bbox)
        if b is None:
            return None
        x0, y0, w, h = b
        a = coverage(sdf, x0, y0, w, h, self.ss, soft) * np.float32(opacity)
        self.blend(a, color, x0, y0)
        return a

    def blend(self, alpha: np.ndarray, color: Color, x0: int = 0, y0: int = 0) -> None:
        h, w = alpha.shape
        region = self.image[y0:y0 + h, x0:x0 + w]
        if callable(color):
            x, y = pixel_centres(x0, y0, w, h, 1)
            col = np.asarray(color(x, y), dtype=np.float32)
        else:
            col = np.asarray(color, dtype=np.float32)
        if region.ndim == 3:
            a = alpha[..., None]
            if col.ndim == 2:
                col = col[..., None]
        else:
            a = alpha
            if col.ndim == 3:
                col = col.mean(axis=2)
        region *= 1 - a
        region += a * col


# --- textures and camera effects -------------------------------------------------------

def value_noise(rng: np.random.Generator, h: int, w: int, scales: tuple[int, ...] = (4, 12, 40),
                weights: tuple[float, ...] | None = None) -> np.ndarray:
    """Smooth seeded noise in about [-1, 1], (h, w) float32: random grids of `scale` cells
    across the width, upsampled bicubically and summed (octaves)."""
    weights = weights or tuple(1.0 / (i + 1) for i in range(len(scales)))
    out = np.zeros((h, w), np.float32)
    for s, wt in zip(scales, weights):
        gw = max(int(s), 2)
        gh = max(int(round(s * h / w)), 2)
        g = rng.standard_normal((gh + 3, gw + 3)).astype(np.float32)
        up = cv2.resize(g, (w + int(np.ceil(3 * w / gw)), h + int(np.ceil(3 * h / gh))),
                        interpolation=cv2.INTER_CUBIC)
        out += wt * up[:h, :w]
    out /= max(float(np.abs(out).max()), 1e-6)
    return out


def vignette(h: int, w: int, strength: float = 0.25) -> np.ndarray:
    """Multiplicative lens fall-off, 1 at the centre and 1 - strength in the corners."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((x + 0.5 - w / 2) / (w / 2)) ** 2 + ((y + 0.5 - h / 2) / (h / 2)) ** 2
    return (1 - strength * r2 / 2).astype(np.float32)


def sphere_shade(cx: float, cy: float, r: float, base: tuple[float, float, float],
                 light: tuple[float, float, float] = (-0.5, -0.6, 0.62), ambient: float = 0.25,
                 specular: float = 0.5, shininess: float = 24.0):
    """Colour function of a Lambert + Phong lit sphere seen head-on (for Canvas.paint)."""
    lx, ly, lz = np.asarray(light) / np.linalg.norm(light)
    base_a = np.asarray(base, np.float32)

    def color(x, y):
        u = (x - cx) / max(r, 1e-6)
        v = (y - cy) / max(r, 1e-6)
        n2 = np.clip(1 - u * u - v * v, 0, 1)
        nz = np.sqrt(n2)
        lam = np.clip(u * lx + v * ly + nz * lz, 0, 1)
        # reflection of the light about the normal, seen by a viewer on +z
        rz = 2 * lam * nz - lz
        spec = specular * np.clip(rz, 0, 1) ** shininess
        return np.clip((ambient + (1 - ambient) * lam)[..., None] * base_a + spec[..., None], 0, 1)
    return color


def jpeg_roundtrip(img_u8: np.ndarray, quality: int) -> np.ndarray:
    """Compress and decompress one uint8 frame (RGB or gray) as a camera's codec would."""
    if quality >= 100:
        return img_u8
    bgr = img_u8[..., ::-1] if img_u8.ndim == 3 else img_u8
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(bgr), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - OpenCV always has a JPEG codec
        return img_u8
    out = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    return out[..., ::-1] if out.ndim == 3 else out
