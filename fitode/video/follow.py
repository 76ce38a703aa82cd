"""Follow the moving object by its appearance, not by the change it makes.

The change detector (fitode.video.track) says where something moves and how large it is; its
centroid is the object's only where nothing else changes and the object never overlaps its own
place in the static scene. Here the detector only seeds: the object is cut out once, in a frame
where it stands clear of its median place and of everything else (its mask: the change there,
opened, holes filled), and that template is then found in every frame, forwards and backwards,
in a window around the place its last two positions predict:

- cv2.matchTemplate (normalised correlation, the object's mask as weights) gives the whole-pixel
  peak;
- a few Gauss-Newton steps of the template's translation, with a gain and an offset for the
  light, weighted by the mask and robustly (Cauchy) against what crosses behind, give the
  sub-pixel place and, from the residuals and the steps' normal matrix, its standard error;
- a frame whose best match correlates under HIDDEN is marked hidden (NaN), never filled with
  whatever stands there; the search widens while the object is lost and covers the frame after
  LOST frames;
- the template follows the object slowly (UPDATE of each well-matched frame, aligned to the
  sub-pixel place first) as it turns and its lighting changes.

The place read is the template's reference point: the centre of the object's mask in the seed
frame (each pixel weighted by how much of it the object covers).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

HIDDEN = 0.5      # a frame whose best match correlates less than this is hidden
UPDATE = 0.05     # the share of a well-matched frame blended into the template
GOOD = 0.85       # ... well-matched: correlation at least this
LOST = 8          # frames lost after which the whole frame is searched
STEPS = 8         # Gauss-Newton steps of the sub-pixel refinement
SEED_FRAMES = 40  # frames the seed is chosen among
MARGIN = 2        # pixels of background kept around the object's mask in the template


@dataclass
class Followed:
    """xy: (T, 2) the object's place (x right, y down) in the frames' pixels, NaN where hidden;
    sigma: (T,) its standard error in pixels (NaN where hidden); score: (T,) the correlation of
    the best match; seed: the frame the template was cut from; area: the object's area in
    pixels; note: one line on how."""

    xy: np.ndarray
    sigma: np.ndarray
    score: np.ndarray
    seed: int
    area: float
    note: str

    @property
    def hidden(self) -> np.ndarray:
        return np.isnan(self.xy[:, 0])


def follow_object(stack: np.ndarray, seed_xy: np.ndarray, background: np.ndarray | None = None,
                  noise: float | None = None) -> Followed | None:
    """The object the change detector found (seed_xy: (T, 2) its path, NaN where it saw nothing)
    followed by its appearance through gray frames (T, H, W) uint8; None where no frame shows it
    clear enough to cut a template."""
    t_all = len(stack)
    if background is None:
        sample = np.unique(np.linspace(0, t_all - 1, min(t_all, 48)).round().astype(int))
        background = np.median(stack[sample], axis=0).round().astype(np.uint8)
    if noise is None:
        noise = float(1.4826 * np.median(np.abs(stack[::max(1, t_all // 8), ::2, ::2].astype(np.int16)
                                                - background[::2, ::2]))) + 0.5
    cut = _seed(stack, seed_xy, background, noise)
    if cut is None:
        return None
    t0, template, weight, ref, area, start = cut
    xy = np.full((t_all, 2), np.nan)
    sigma = np.full(t_all, np.nan)
    score = np.full(t_all, np.nan)
    size = math.sqrt(area)
    for way in (1, -1):
        tmpl = template.copy()
        last: list[np.ndarray] = []
        lost = 0
        ts = range(t0, t_all) if way == 1 else range(t0 - 1, -1, -1)
        if way == -1:
            last = [xy[t0]] if np.isfinite(xy[t0, 0]) else []
            if t0 + 1 < t_all and np.isfinite(xy[t0 + 1, 0]) and last:
                last = [xy[t0 + 1], xy[t0]]
        for t in ts:
            frame = stack[t].astype(np.float32)
            if t == t0:
                guess, reach = start, 2.0
            elif not last:
                guess, reach = None, None
            else:
                velocity = last[-1] - last[-2] if len(last) > 1 else np.zeros(2)
                guess = last[-1] + velocity * (lost + 1)
                reach = max(3.0 * float(np.linalg.norm(velocity)), 0.5 * size, 6.0) * (1 + lost)
                if lost >= LOST:
                    guess = None
            found = _find(frame, tmpl, weight, ref, guess, reach)
            if found is None or found[2] < HIDDEN:
                lost += 1
                continue
            place, se, corr, patch = found
            xy[t], sigma[t], score[t] = place, se, corr
            last = (last + [place])[-2:]
            lost = 0
            if corr >= GOOD:
                tmpl = (1 - UPDATE) * tmpl + UPDATE * patch
    seen = np.isfinite(xy[:, 0])
    note = (f"the object followed by its appearance (a template of {area:.0f} pixels cut from frame {t0}, "
            f"hidden in {int((~seen).sum())} of {t_all} frames)")
    return Followed(xy, sigma, score, t0, float(area), note)


def _seed(stack, seed_xy, background, noise):
    """The frame to cut the template from and the cut: (frame, template (h, w) float32, weight
    (h, w), ref (the reference point in the template's pixels), area). Among SEED_FRAMES frames
    where the detector saw something, those whose object region has about the median area (not
    merged with a hand or a leg), the one farthest from the path's median place (its place in the
    static scene is clean there)."""
    seen = np.flatnonzero(np.isfinite(seed_xy[:, 0]))
    if len(seen) < 3:
        return None
    pick = seen[np.unique(np.linspace(0, len(seen) - 1, min(len(seen), SEED_FRAMES)).round().astype(int))]
    cuts = {}
    for t in pick:
        cut = _cut(stack[t], background, noise, seed_xy[t])
        if cut is not None:
            cuts[int(t)] = cut
    if not cuts:
        return None
    areas = np.array([c[4] for c in cuts.values()])
    typical = float(np.median(areas))
    middle = np.nanmedian(seed_xy, axis=0)
    best, far = None, -1.0
    for t, c in cuts.items():
        if not 0.7 * typical <= c[4] <= 1.4 * typical:
            continue
        d = float(np.linalg.norm(c[5] - middle))
        if d > far:
            best, far = t, d
    if best is None:
        return None
    template, weight, ref, _, area, centre = cuts[best]
    return best, template, weight, ref, area, centre


def _cut(frame, background, noise, near):
    """The object around `near` in one frame: (template, weight, ref, box, area, centre) or None."""
    change = cv2.absdiff(frame, background).astype(np.float32)
    h, w = change.shape
    low = 4.0 * noise
    hot = (change > low).astype(np.uint8)
    hot = cv2.morphologyEx(hot, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))  # a string, a spring: not the object
    n, labels, stats, _ = cv2.connectedComponentsWithStats(cv2.dilate(hot, None), connectivity=8)
    if n < 2:
        return None
    x, y = int(round(float(near[0]))), int(round(float(near[1])))
    if not (0 <= x < w and 0 <= y < h):
        return None
    k = labels[y, x]
    if k == 0:  # the centroid of a ring or a crescent may lie outside it: the nearest region
        ys, xs = np.nonzero(labels)
        if not len(xs):
            return None
        j = int(np.argmin((xs - x) ** 2 + (ys - y) ** 2))
        k = labels[ys[j], xs[j]]
    bx, by, bw, bh, _ = (int(v) for v in stats[k])
    region = (labels == k).astype(np.uint8) & hot
    # holes filled (a stripe the colour of the wall is still the object)
    outside = np.pad(region, 1)
    cv2.floodFill(outside, None, (0, 0), 1)  # what stays 0 is enclosed by the region
    filled = region | (outside[1:-1, 1:-1] == 0).astype(np.uint8)
    # each pixel weighted by how much of it the object covers: its change over the core's typical change
    core = change[filled > 0]
    if core.size < 2:
        return None
    full = max(float(np.median(core)), low)
    cover = np.clip(change / full, 0.0, 1.0)
    cover = np.where(filled > 0, 1.0, np.where(cv2.dilate(filled, None) > 0, cover, 0.0))
    area = float(cover.sum())
    x0, y0 = max(bx - MARGIN, 0), max(by - MARGIN, 0)
    x1, y1 = min(bx + bw + MARGIN, w), min(by + bh + MARGIN, h)
    c = cover[y0:y1, x0:x1]
    ys, xs = np.mgrid[y0:y1, x0:x1]
    centre = np.array([float((c * xs).sum() / c.sum()), float((c * ys).sum() / c.sum())])
    # the template's weight: the object and a ring of MARGIN pixels of what surrounds it (its edge)
    weight = cv2.dilate((c > 0).astype(np.uint8), np.ones((2 * MARGIN + 1, 2 * MARGIN + 1), np.uint8)).astype(np.float32)
    template = frame[y0:y1, x0:x1].astype(np.float32)
    return template, weight, centre - np.array([x0, y0]), (x0, y0, x1, y1), area, centre


def _find(frame, template, weight, ref, guess, reach):
    """The template's best place in the frame: (place (2,), standard error, correlation, the
    frame's patch aligned there) or None."""
    th, tw = template.shape
    h, w = frame.shape
    if guess is None:
        x0, y0, x1, y1 = 0, 0, w, h
    else:
        gx, gy = guess - ref  # the template's top-left corner
        x0, y0 = int(math.floor(gx - reach)), int(math.floor(gy - reach))
        x1, y1 = int(math.ceil(gx + reach)) + tw + 1, int(math.ceil(gy + reach)) + th + 1
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 - x0 < tw or y1 - y0 < th:
        return None
    window = frame[y0:y1, x0:x1]
    corr = cv2.matchTemplate(window, template, cv2.TM_CCORR_NORMED if _flat(template) else cv2.TM_CCOEFF_NORMED,
                             mask=weight)
    corr = np.nan_to_num(corr, nan=-1.0, posinf=-1.0, neginf=-1.0)
    j = int(np.argmax(corr))
    py, px = divmod(j, corr.shape[1])
    place = np.array([x0 + px, y0 + py], dtype=np.float64) + ref
    return _refine(frame, template, weight, ref, place)


def _flat(template: np.ndarray) -> bool:
    return float(template.std()) < 1e-3


def _refine(frame, template, weight, ref, place):
    """Gauss-Newton on the template's translation (with a gain and an offset for the light),
    robustly weighted; (place, standard error, weighted correlation, aligned patch) or None."""
    th, tw = template.shape
    t_vec = template.ravel().astype(np.float64)
    wgt = weight.ravel().astype(np.float64)
    offset = np.array([(tw - 1) / 2.0, (th - 1) / 2.0]) - ref  # the patch centre from the reference point
    robust = np.ones_like(wgt)
    se = math.inf
    for step in range(STEPS):
        centre = place + offset
        patch = cv2.getRectSubPix(frame, (tw, th), (float(centre[0]), float(centre[1])))
        if patch is None:
            return None
        gy, gx = np.gradient(patch.astype(np.float64))
        p = patch.ravel().astype(np.float64)
        jac = np.column_stack([gx.ravel(), gy.ravel(), -t_vec, -np.ones_like(t_vec)])
        ww = wgt * robust
        a = jac.T @ (jac * ww[:, None])
        try:
            d = np.linalg.solve(a, -(jac.T @ (ww * p)))
        except np.linalg.LinAlgError:
            return None
        resid = p + jac @ d  # the residual after the step, to first order
        s2 = float((ww * resid ** 2).sum() / max(ww.sum() - 4, 1.0))
        scale = math.sqrt(max(s2, 1e-6))
        robust = 1.0 / (1.0 + (resid / (3.0 * scale)) ** 2)
        d_xy = np.clip(d[:2], -1.0, 1.0)  # the linearisation holds within about a pixel
        place = place + d_xy
        if float(np.abs(d_xy).max()) < 1e-3:
            break
    try:
        cov = np.linalg.inv(a) * s2
        se = math.sqrt(max(float(cov[0, 0] + cov[1, 1]), 0.0))
    except np.linalg.LinAlgError:
        se = math.inf
    centre = place + offset
    patch = cv2.getRectSubPix(frame, (tw, th), (float(centre[0]), float(centre[1]))).astype(np.float32)
    pm, tm = patch[weight > 0], template[weight > 0]
    pc, tc = pm - pm.mean(), tm - tm.mean()
    corr = float((pc * tc).sum() / math.sqrt(max(float((pc ** 2).sum() * (tc ** 2).sum()), 1e-12)))
    return place, se, corr, patch
