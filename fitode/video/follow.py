"""Follow the moving object by its appearance, not by the change it makes.

The change detector (fitode.video.track) says where something moves and how large it is; its
centroid is the object's only where nothing else changes and the object never overlaps its own
place in the static scene. Here the detector only seeds: the object is cut out once, in a frame
where it stands clear of its median place and of everything else (its mask: the change there,
opened, holes filled), and that template is then found in every frame, forwards and backwards,
in a window around the place its last two positions predict:

- cv2.matchTemplate (normalised correlation, the object's mask as weights) gives the whole-pixel
  peak (a template COARSE pixels across or more is matched at half the resolution, the refinement
  below starting from there); the predicted place itself is refined too (something passing behind
  may hold the peak);
- a few Gauss-Newton steps of the template's translation, with a gain and an offset for the
  light, weighted by the mask and robustly (Cauchy) against what crosses behind (an edge pixel
  trusted no more than the surroundings next to it), give the sub-pixel place and, from the residuals and the steps' normal matrix, its standard error;
- a frame whose best match correlates under HIDDEN is marked hidden (NaN), never filled with
  whatever stands there (nor a fair match beside such a frame); the search widens while the
  object is lost and covers the frame after LOST frames; a lost object is cut afresh from the
  change where it was going, where that change has its size and its old template still finds it;
- the template follows the object slowly (UPDATE of each well-matched frame, aligned to the
  sub-pixel place first) as it turns and its lighting changes.

The place read is the template's reference point: the centre of the object in the seed frame
(each pixel weighted by how much of it the object covers, an edge pixel by its change over that of
the object's inside next to it), cut, once its motion is known, from what moves with it and then
from each frame against the static scene with the object taken out (_outline, _centre): the seed's own cut
is a crescent where the object covers its place in the static scene.

The reader (fitode.video.track.TrackRecorder) takes this track where the change detector's path
switches between moving things and this one follows another, or where both follow the same object
and this one scatters less from frame to frame (choose).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import cv2
import numpy as np

HIDDEN = 0.5      # a frame whose best match correlates less than this is hidden
UPDATE = 0.1      # the share of each placed frame blended into the template's object pixels
GOOD = 0.85      # ... well-matched: correlation at least this
LOST = 8          # frames lost after which the whole frame is searched
STEPS = 8         # Gauss-Newton steps of the sub-pixel refinement
SEED_FRAMES = 40  # frames the seed is chosen among
PEAKS = 1         # the correlation's peaks refined where the best is not a good match
MARGIN = 2        # pixels of background kept around the object's mask in the template
OFFSET = 0.25     # the largest change of the object's brightness (beyond a gain) a match allows, in its contrasts
BACKGROUND_FRAMES = 48  # frames spread over the clip whose median is the static scene (static_scene)
TRAVEL_TURN = 1.0  # pixels a path comes back by, at least, for a turn of it to count (travelled)
WHOLE = 1.2      # the object followed again with its whole cut where that has this many times the seed cut's area
OWN_FRAMES = 16  # frames whose own change places the object's centre (_centre)
OFF_CENTRE = 1.0  # ... or where the template's reference point lies this many pixels from that centre
EDGE = 2          # pixels on either side of the object's outline that mix it with what lies behind
RING_QUANTILE = 0.25  # the share of the ring around the object that must still show what surrounded it


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
    rigid: np.ndarray | None = None  # (T,) the score against the seed frame's template (how much the object keeps its look)

    @property
    def hidden(self) -> np.ndarray:
        return np.isnan(self.xy[:, 0])


def follow_object(stack: np.ndarray, seed_xy: np.ndarray, background: np.ndarray | None = None,
                  noise: float | None = None) -> Followed | None:
    """The object the change detector found (seed_xy: (T, 2) its path, NaN where it saw nothing)
    followed by its appearance through gray frames (T, H, W) uint8; None where no frame shows it
    clear enough to cut a template."""
    t_all = len(stack)
    if background is None or noise is None:
        _, background, noise = static_scene(stack)
    cut = _seed(stack, seed_xy, background, noise)
    if cut is None:
        return None
    t0, template, weight, ref, area, start = cut
    xy, sigma, score, rigid = _track(stack, seed_xy, t0, template, weight, ref, area, start, background, noise)
    shift = np.zeros(2)
    outline = _outline(stack, xy, t0, template.shape, ref, noise, background)
    if outline is not None:
        sample, cut, clear = outline
        shift, whole = _centre(stack, xy, t0, sample, cut, clear, noise)
        if whole is not None and (whole[4] >= WHOLE * area or float(np.hypot(*shift)) > OFF_CENTRE):
            # the seed's cut was a crescent of the object (it covered its own place in the static
            # scene): a template without one of its ends leaves the object free to slide along it
            # where something passes behind the other (the can on its spring: 7 px as a leg
            # passed), and its reference point, away from the centre, turns about it as it turns
            # (a can cut 2.6 px off its centre, turning by 0.2 rad: 0.6 px);
            # the second following is kept where it places the object as often and keeps its look as well (a whole cut that
            # took in a part of the scene beside the object follows it worse)
            again = _track(stack, seed_xy, t0, whole[0], whole[1], whole[2], whole[4], whole[5], background, noise)
            if _as_well(again, (xy, sigma, score, rigid)):
                xy, sigma, score, rigid = again
                template, weight, ref, area = whole[0], whole[1], whole[2], whole[4]
                shift, _ = _centre(stack, xy, t0, sample, cut, clear, noise)
    xy += shift
    seen = np.isfinite(xy[:, 0])
    note = (f"the object followed by its appearance (a template of {area:.0f} pixels cut from frame {t0}, "
            f"hidden in {int((~seen).sum())} of {t_all} frames)")
    return Followed(xy, sigma, score, t0, float(area), note, rigid)


def _as_well(again, first) -> bool:
    """Whether a second following (xy, sigma, score, rigid) places the object in as many frames as
    the first (to a hundredth of them) with a median score and a median score against its own seed
    template as high (to 0.02)."""
    seen_a, seen_f = np.isfinite(again[0][:, 0]), np.isfinite(first[0][:, 0])
    if not seen_a.any() or seen_a.mean() < seen_f.mean() - 0.01:
        return False
    return all(float(np.median(a[seen_a])) >= float(np.median(f[seen_f])) - 0.02
               for a, f in ((again[2], first[2]), (again[3], first[3])))


def _track(stack, seed_xy, t0, template, weight, ref, area, start, background, noise):
    """The template (its reference point at start in frame t0) followed forwards and backwards
    from t0: (xy, sigma, score, rigid), each (T, ...) as Followed's, xy the reference point's place."""
    t_all = len(stack)
    xy = np.full((t_all, 2), np.nan)
    sigma = np.full(t_all, np.nan)
    score = np.full(t_all, np.nan)
    rigid = np.full(t_all, np.nan)  # the score against the seed's template, not the one that follows the object
    size = math.sqrt(area)
    for way in (1, -1):
        tmpl, wgt, rf = template.copy(), weight, ref
        last: list[np.ndarray] = []
        lost, angle = 0, 0.0
        detected = np.full(2, np.nan)
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
                reach = max(3.0 * float(np.linalg.norm(velocity)), 0.25 * size, 4.0) * (1 + lost)
                if lost >= LOST:
                    guess = None
            found = _find(frame, tmpl, wgt, rf, guess, reach, angle)
            if found is not None:
                score[t] = found[2]
            if (found is None or found[2] < GOOD) and lost and guess is not None:
                # lost a while (legs passed behind, the label went round meanwhile): the object
                # cut afresh from the change where it was going, if that change has its size
                again = _cut(stack[t], background, noise, guess)
                if (again is not None and 0.8 * area <= again[4] <= 1.25 * area
                        and float(np.linalg.norm(again[5] - guess)) <= reach):
                    new_ref = _aligned(again[1], weight, ref)
                    place = again[5] - again[2] + new_ref
                    # and it is the object where the template it had still finds it there (a
                    # region of the can's size may be a leg's piece beside its top)
                    if _score(_sample(frame, place, angle, rf, tmpl.shape), tmpl, wgt) >= HIDDEN:
                        tmpl, wgt, rf = again[0], again[1], new_ref
                        found = _refine(frame, tmpl, wgt, rf, place, 0.0)
                        if found is not None:
                            score[t] = found[2]
            if found is None or found[2] < HIDDEN:
                lost += 1
                continue
            place, se, corr, patch, turned = found
            # a match away from where the object should be is taken only where it matches well
            # (the object taken up again after it was hidden); a poor one is something else
            # while the object is followed, a jump away from its predicted place is something else
            # however well it matches (the can's spring and a leg behind it), unless it lies where
            # the change detector's path is too (the template's place from it in the frame last
            # placed): the motion may change at once (a ball that stops dead, followed backwards)
            there = seed_xy[t] + detected
            far = guess is None or (float(np.linalg.norm(place - guess)) > 0.25 * size + 2.0
                                    and not float(np.linalg.norm(place - there)) <= 0.25 * size + 2.0)
            if far and (corr < GOOD or not lost):
                lost += 1
                continue
            xy[t], sigma[t], score[t] = place, se, corr
            if np.isfinite(seed_xy[t, 0]):  # where the template's place lies from the detector's
                detected = place - seed_xy[t]
            rigid[t] = _score(patch, template, weight) if patch.shape == template.shape else corr
            # taken up again after frames lost: its step from the place before the loss is not one frame's
            last = (last + [place])[-2:] if not lost else [place]
            lost, angle = 0, turned
            # the object's own pixels follow its look (a label that goes round, the light); the ring
            # around it keeps the seed's: what passes behind is not learnt
            tmpl = np.where(wgt >= 1.0, (1 - UPDATE) * tmpl + UPDATE * patch, tmpl)
    # a frame beside a hidden one that matches only fairly is half hidden: what covers the object
    # there pulls its place (by pixels, on the can as a leg passes behind)
    for _ in range(2):
        gone = np.isnan(xy[:, 0])
        edge = np.zeros(t_all, bool)
        edge[1:] |= gone[:-1]
        edge[:-1] |= gone[1:]
        doubt = edge & ~gone & (score < GOOD)
        xy[doubt], sigma[doubt] = np.nan, np.nan
    if np.isfinite(sigma).sum() > 1:  # the seed frame matches itself exactly: its error is like its neighbours'
        sigma[t0] = float(np.nanmedian(np.delete(sigma, t0)))
    return xy, sigma, score, rigid


def follow_best(stack: np.ndarray, paths: np.ndarray) -> Followed | None:
    """Of the change detector's paths (n, T, 2; the strongest first), the object followed best:
    among those that move, the one in view longest (to a tenth of the frames), and of those the
    one that keeps its look best (the median score against the seed frame's template).
    The strongest change is not always the object: legs walking behind a can on a spring change
    more; they also change their shape as they go."""
    _, background, noise = static_scene(stack)
    best, rank = None, None
    for path in paths:
        if np.isfinite(path[:, 0]).sum() < 3:
            continue
        found = follow_object(stack, path, background, noise)
        if found is None:
            continue
        seen = np.isfinite(found.xy[:, 0])
        # an object that travels less than its own size is not the one that moves (a hand that
        # has let the ball go)
        if seen.sum() < 3 or travelled(found.xy[seen]) < max(2.0, math.sqrt(found.area)):
            continue
        # in view longest (to a tenth of the clip: legs walk out of the view, a can on its spring
        # does not), then keeping its look best
        key = (round(float(seen.mean()), 1), float(np.nanmedian(found.rigid[seen])))
        if rank is None or key > rank:
            best, rank = found, key
    return best


def travelled(xy: np.ndarray) -> float:
    """How far a path (T, 2) travels: along each image axis, the sum of its swings from one turning
    point to the next, a turn counted where the path comes back by more than TRAVEL_TURN pixels or
    4 times its frame-to-frame scatter (so that the noise of a still thing's place adds nothing);
    the larger axis's. A swing narrower than the object that swings (a large bob on a small swing,
    its string in the template: 43 pixels of range for 43 of size) travels its range on every
    swing; a hand that has let go moves once, if at all."""
    p = xy[np.isfinite(xy[:, 0]) & np.isfinite(xy[:, 1])]
    if len(p) < 2:
        return 0.0
    noise = scatter(p)
    turn = max(TRAVEL_TURN, 4.0 * noise) if math.isfinite(noise) else TRAVEL_TURN
    return max(_swings(p[:, 0], turn), _swings(p[:, 1], turn))


def _swings(v: np.ndarray, turn: float) -> float:
    """The summed lengths of a series' swings between turning points, a turn taken where it comes
    back from its extreme by more than `turn`, and its last swing to its last extreme."""
    total, start, extreme, up = 0.0, float(v[0]), float(v[0]), None
    for x in map(float, v[1:]):
        if up is None:
            if abs(x - start) > turn:
                up, extreme = x > start, x
        elif (x > extreme) == up and x != extreme:
            extreme = x
        elif abs(x - extreme) > turn:
            total += abs(extreme - start)
            start, extreme, up = extreme, x, not up
    return total + (abs(extreme - start) if up is not None else 0.0)


def static_scene(stack: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The frames (up to BACKGROUND_FRAMES, spread over the clip) the static scene is the median
    of, that median, and the noise of a frame's difference from it, as one pixel's standard
    deviation (most pixels show only noise): what the change detector (fitode.video.track), the
    object tracker and the water line measure against."""
    sample = np.unique(np.linspace(0, len(stack) - 1, min(len(stack), BACKGROUND_FRAMES)).round().astype(int))
    background = np.median(stack[sample], axis=0).round().astype(np.uint8)
    noise = float(1.4826 * np.median(np.abs(stack[sample[::6], ::2, ::2].astype(np.int16)
                                            - background[::2, ::2]))) + 0.5
    return sample, background, noise


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


def _cut(frame, background, noise, near, change=None, bridge: int = 0, centre: bool = False):
    """The object around `near` in one frame: (template, weight, ref, box, area, centre) or None
    (change: the frame's change from the static scene, where the caller knows it better; bridge:
    the width in pixels of the gaps closed between its parts, which then count as the object's;
    centre: the cut places the object's centre, its edge pixels weighed as _cover does, not by one
    level of full change for the whole object, as the template's mask is)."""
    if change is None:
        change = cv2.absdiff(frame, background).astype(np.float32)
    h, w = change.shape
    low = 4.0 * noise
    hot = (change > low).astype(np.uint8)
    hot = cv2.morphologyEx(hot, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))  # a string, a spring: not the object
    if bridge > 1:
        # an object's parts the colour of what lies behind it change nothing (the light bands of a
        # printed block on a light wall): the parts around them that do are joined across them
        joined = cv2.morphologyEx(hot, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (bridge, bridge)))
        bridged, hot = joined > hot, joined
    else:
        bridged = np.zeros(hot.shape, bool)
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
    region = (labels == k).astype(np.uint8) & hot
    # thin parts hanging on the object (a pendulum's string, a spring's coils) are not the object:
    # the region opened by the widest square under a third of its narrower side
    bw, bh = int(stats[k, 2]), int(stats[k, 3])
    side = 2 * (min(bw, bh) // 6) + 1
    if side >= 5:
        opened = cv2.morphologyEx(region, cv2.MORPH_OPEN, np.ones((side, side), np.uint8))
        n2, lab2, st2, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
        if n2 > 1:
            keep = 1 + int(np.argmax(st2[1:, cv2.CC_STAT_AREA]))
            region = (lab2 == keep).astype(np.uint8)
    ys_r, xs_r = np.nonzero(region)
    if not len(xs_r):
        return None
    bx, by = int(xs_r.min()), int(ys_r.min())
    bw, bh = int(xs_r.max()) - bx + 1, int(ys_r.max()) - by + 1
    # holes filled (a stripe the colour of the wall is still the object)
    outside = np.pad(region, 1)
    cv2.floodFill(outside, None, (0, 0), 1)  # what stays 0 is enclosed by the region
    filled = region | (outside[1:-1, 1:-1] == 0).astype(np.uint8)
    # each pixel weighted by how much of it the object covers: its change over the core's typical change
    # (an edge pixel by its share: a threshold would move a small object's centre by a good part of
    # a pixel; a hole, a part the colour of the wall, in full)
    # full cover: what the object's inside differs by at its least (a low quantile: a shaded ball
    # differs less on its lit side, and is whole there too)
    inside_px = cv2.erode(region, np.ones((3, 3), np.uint8))
    inside_px &= ~bridged  # a bridged gap changes nothing: it says nothing of the object's full change
    core = change[inside_px > 0] if inside_px.sum() >= 4 else change[(region > 0) & ~bridged]
    if core.size < 2:
        return None
    full = max(float(np.quantile(core, 0.1)), low)
    cover = _cover(change, filled, bridged, full, low) if centre else np.clip(change / full, 0.0, 1.0)
    # a gap bridged inside the object is the object's; one on its outline may be the notch between
    # it and a thin part cut off (the spring's last coil on the can's top) and counts by its change
    inner_gap = bridged & (region > 0) & (cv2.erode(filled, np.ones((5, 5), np.uint8)) > 0)
    cover = np.where((filled > region) | inner_gap, 1.0, np.where(cv2.dilate(filled, None) > 0, cover, 0.0))
    area = float(cover.sum())
    x0, y0 = max(bx - MARGIN, 0), max(by - MARGIN, 0)
    x1, y1 = min(bx + bw + MARGIN, w), min(by + bh + MARGIN, h)
    c = cover[y0:y1, x0:x1]
    ys, xs = np.mgrid[y0:y1, x0:x1]
    centre = np.array([float((c * xs).sum() / c.sum()), float((c * ys).sum() / c.sum())])
    # the template's weight: the object and a ring of MARGIN pixels of what surrounds it (its edge)
    # (the ring weighs half: what passes behind the object changes it); the correlation that says
    # whether the object is in view is taken over the object's own pixels (weight 1)
    inner = (c >= 0.5).astype(np.uint8)
    ring = cv2.dilate(inner, np.ones((2 * MARGIN + 1, 2 * MARGIN + 1), np.uint8))
    weight = np.where(inner > 0, 1.0, np.where(ring > 0, 0.5, 0.0)).astype(np.float32)
    template = frame[y0:y1, x0:x1].astype(np.float32)
    return template, weight, centre - np.array([x0, y0]), (x0, y0, x1, y1), area, centre


def _cover(change, filled, bridged, full, low) -> np.ndarray:
    """How much of each pixel the object covers (H, W), from 0 to 1: wholly two pixels and more
    inside its outline (filled), where the camera's blur no longer reaches the background; on
    its edge, its change over the change of the object's inside next to it. One level for the
    whole object would weigh a printed object's bands that differ less from the wall as part
    covered and move its centre towards those that differ most (a banded block: 0.5-0.9 px);
    an edge where a band meets the wall differs as that band does. full: the level where no
    inside lies near (an object too small to have one)."""
    deep = (cv2.erode(filled, np.ones((5, 5), np.uint8)) > 0) & ~bridged
    if not deep.any():
        return np.clip(change / full, 0.0, 1.0)
    near = cv2.boxFilter(deep.astype(np.float32), -1, (5, 5), normalize=False)
    level = cv2.boxFilter(np.where(deep, change, 0.0).astype(np.float32), -1, (5, 5), normalize=False)
    local = np.where(near > 0, level / np.maximum(near, 1e-6), full)
    return np.where(deep, 1.0, np.clip(change / np.maximum(local, low), 0.0, 1.0)).astype(np.float32)


def _aligned(new_weight, old_weight, old_ref, pad: int = 6) -> np.ndarray:
    """The reference point in a fresh cut's pixels that the seed's template has in its own: the
    two silhouettes (the weights) laid on each other (a parabola through the correlation's peak).
    A fresh cut's own centre may differ by pixels from the seed's (a spring's coil kept, a shaded
    top lost); the outline less (on the generated can: 0.6 and 2.3 pixels off still)."""
    big = np.pad(new_weight.astype(np.float32), pad)
    small = old_weight.astype(np.float32)
    if big.shape[0] < small.shape[0] or big.shape[1] < small.shape[1]:
        return np.asarray(old_ref, dtype=np.float64)
    corr = cv2.matchTemplate(big, small, cv2.TM_CCORR_NORMED)
    py, px = np.unravel_index(int(np.argmax(corr)), corr.shape)
    sub = []
    for k, (i, n) in enumerate(((px, corr.shape[1]), (py, corr.shape[0]))):
        if 0 < i < n - 1:
            a, b, c = (corr[py, i - 1], corr[py, i], corr[py, i + 1]) if k == 0 else (corr[i - 1, px], corr[i, px], corr[i + 1, px])
            den = a - 2 * b + c
            sub.append(i + (0.5 * (a - c) / den if den < 0 else 0.0))
        else:
            sub.append(float(i))
    return np.array(sub) - pad + np.asarray(old_ref, dtype=np.float64)


def _outline(stack, xy, t0, shape, ref, noise, background):
    """The whole object's outline in the seed frame t0, once its motion (xy: the template's
    reference point's place per frame) is known: (sample, cut, clear) with the frames it is read
    over, its cut (as _cut) and the static scene with the object taken out; None where no cut is
    made. The seed's cut is the change from the clip's median frame, and where the object covers
    its own median place (a large object, a slow swing) that median holds part of it: the cut is a
    crescent, and which part is missing moves as the object does. Each frame's change from the
    median frame is moved back with the object onto the seed frame, and the median over up to 48
    frames is what moves with the object: the whole of it, wherever it stood clear of its median
    place in most of them (what crosses behind it does not follow it). The object is cut from
    that, its parts joined across gaps up to a quarter of its narrower side (a printed block's
    bands the colour of the wall change nothing). An edge along the object's motion stays where
    the median frame holds the object (a block swinging sideways: its top and bottom, by pixels),
    so the cut is made again against the scene with the object taken out (_without)."""
    seen = np.flatnonzero(np.isfinite(xy[:, 0]))
    if len(seen) < 8 or not np.isfinite(xy[t0, 0]):
        return None
    sample = seen[np.unique(np.linspace(0, len(seen) - 1, min(len(seen), 48)).round().astype(int))]
    th, tw = shape
    cut = _whole(stack, xy, t0, sample, xy[t0] - ref, (th, tw), noise, background)
    if cut is None:
        return None
    bx0, by0, bx1, by1 = cut[3]
    clear = _without(stack, xy, t0, sample, cut[3], background)
    again = _whole(stack, xy, t0, sample, np.array([bx0, by0], np.float64), (by1 - by0, bx1 - bx0), noise, clear)
    return (sample, cut, background) if again is None else (sample, again, clear)


def _centre(stack, xy, t0, sample, outline, clear, noise):
    """The shift (2,) from the places xy (T, 2) to the object's centre, and the whole object cut
    in frame t0 (as _cut; None where it was not cut there with its usual area); outline: its cut
    in frame t0 (_outline). The centre is read from each frame's own change from the scene without
    the object (clear) inside the outline, not from the moved frames: those are resampled at a
    fraction of a pixel, which smears each edge by its own contrast (a striped ball on a textured
    wall: a fifth of a pixel); the median over up to OWN_FRAMES frames in which the object has its
    usual area (a frame's edge pixels read its cover through the wall's texture and the camera's
    noise). The shift is taken in the frame's axes: it holds as the object turns only where xy
    is near its centre."""
    weight, (bx0, by0, bx1, by1) = outline[1], outline[3]
    ring = cv2.dilate((weight > 0).astype(np.uint8), np.ones((5, 5), np.uint8))
    side = min(by1 - by0, bx1 - bx0)
    h, w = stack.shape[1:]
    shifts, areas, whole = [], [], None
    few = sample[np.unique(np.linspace(0, len(sample) - 1, min(len(sample), OWN_FRAMES)).round().astype(int))]
    for t in np.union1d(few, [t0]):
        if not np.isfinite(xy[t, 0]):
            continue
        dx, dy = (xy[t] - xy[t0]).round().astype(int)
        inside = np.zeros((h, w), np.uint8)
        ox0, oy0 = bx0 + dx, by0 + dy
        ix0, iy0, ix1, iy1 = max(ox0, 0), max(oy0, 0), min(ox0 + ring.shape[1], w), min(oy0 + ring.shape[0], h)
        if ix1 <= ix0 or iy1 <= iy0:
            continue
        inside[iy0:iy1, ix0:ix1] = ring[iy0 - oy0:iy1 - oy0, ix0 - ox0:ix1 - ox0]
        own = np.where(inside > 0, cv2.absdiff(stack[t], clear), 0).astype(np.float32)
        cut = _cut(stack[t], None, noise, xy[t], own, bridge=2 * (side // 8) + 1, centre=True)
        if cut is not None:
            shifts.append(cut[5] - xy[t])
            areas.append(cut[4])
            if t == t0:
                whole = cut
    if not shifts:
        return outline[5] - xy[t0], None
    typical = _typical(areas)
    if whole is not None and abs(math.log(whole[4] / float(np.median(areas)))) > 0.1:
        whole = None
    return np.median(np.array(shifts)[typical], axis=0), whole


def _typical(areas) -> np.ndarray:
    """The cuts whose area lies within 10% of the median area; never none (two areas 40% apart
    are both off their median, and a median of no shift was NaN: the real drop's warning)."""
    off = np.abs(np.log(np.asarray(areas, dtype=float) / np.median(areas)))
    return off <= max(0.1, float(off.min()))


def _whole(stack, xy, t0, sample, corner, shape, noise, background):
    """The object cut (as _cut) in the seed frame t0 from the median of the sampled frames' change
    from the background, each moved back with the object; the window around the box at corner
    (x, y) of shape (h, w) widens until the object fits. None where nothing is cut."""
    h, w = stack.shape[1:]
    th, tw = shape
    grow = max(th, tw) + 4  # the crescent may be a small part of the object: the window widens until the object fits
    cut = None
    for _ in range(3):
        x0, y0 = int(max(math.floor(corner[0]) - grow, 0)), int(max(math.floor(corner[1]) - grow, 0))
        x1, y1 = int(min(math.ceil(corner[0]) + tw + grow, w)), int(min(math.ceil(corner[1]) + th + grow, h))
        # at most 64 MiB of moved frames (a large object in a large frame: fewer of them)
        few = max(8, min(len(sample), 2 ** 26 // (4 * (y1 - y0) * (x1 - x0))))
        use = sample[np.unique(np.linspace(0, len(sample) - 1, few).round().astype(int))]
        moved = np.empty((len(use), y1 - y0, x1 - x0), np.float32)
        for i, t in enumerate(use):
            dx, dy = xy[t] - xy[t0]  # the window's pixel (u, v) lies at (x0 + u + dx, y0 + v + dy) in frame t
            m = np.array([[1.0, 0.0, x0 + dx], [0.0, 1.0, y0 + dy]])
            moved[i] = cv2.warpAffine(cv2.absdiff(stack[t], background).astype(np.float32), m, (x1 - x0, y1 - y0),
                                      flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                      borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
        with warnings.catch_warnings():  # a pixel outside every frame it was moved to
            warnings.simplefilter("ignore", RuntimeWarning)
            follows = np.nan_to_num(np.nanmedian(moved, axis=0))
        change = np.zeros((h, w), np.float32)
        change[y0:y1, x0:x1] = follows
        hot = cv2.morphologyEx((change > 4.0 * noise).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        ys, xs = np.nonzero(hot)
        if not len(xs):
            return None
        side = min(int(np.ptp(xs)), int(np.ptp(ys))) + 1
        cut = _cut(stack[t0], None, noise, xy[t0], change, bridge=2 * (side // 8) + 1, centre=True)
        if cut is None:
            return None
        bx0, by0, bx1, by1 = cut[3]
        if (bx0 > x0 or x0 == 0) and (by0 > y0 or y0 == 0) and (bx1 < x1 or x1 == w) and (by1 < y1 or y1 == h):
            break
        grow *= 2
    return cut


def _without(stack, xy, t0, sample, box, background) -> np.ndarray:
    """The static scene (H, W) uint8 with the object taken out: where the object passed, each
    pixel's median over the sampled frames in which the object's box (box: (x0, y0, x1, y1) in
    frame t0, widened by a tenth of its size for what the cut missed of it) lay elsewhere; a pixel
    the box covered in all but two of them is drawn in from around it (cv2.inpaint). The clip's
    median frame holds the object wherever it stood more than half the time."""
    h, w = stack.shape[1:]
    x0, y0, x1, y1 = box
    pad = max(3, int(math.ceil(0.1 * max(x1 - x0, y1 - y0))))
    x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
    moves = (xy[sample] - xy[t0]).round().astype(int)
    # the swept region: where the object's box lay in any sampled frame
    sx0, sy0 = max(x0 + int(moves[:, 0].min()), 0), max(y0 + int(moves[:, 1].min()), 0)
    sx1, sy1 = min(x1 + int(moves[:, 0].max()), w), min(y1 + int(moves[:, 1].max()), h)
    if sx1 <= sx0 or sy1 <= sy0:
        return background
    few = max(8, min(len(sample), 2 ** 26 // (4 * (sy1 - sy0) * (sx1 - sx0))))  # at most 64 MiB
    pick = np.unique(np.linspace(0, len(sample) - 1, few).round().astype(int))
    crops = np.empty((len(pick), sy1 - sy0, sx1 - sx0), np.float32)
    for i, k in enumerate(pick):
        crops[i] = stack[sample[k], sy0:sy1, sx0:sx1]
        dx, dy = moves[k]
        crops[i, max(y0 + dy - sy0, 0):max(y1 + dy - sy0, 0), max(x0 + dx - sx0, 0):max(x1 + dx - sx0, 0)] = np.nan
    clear = background.copy()
    with warnings.catch_warnings():  # a pixel the object covered in every sampled frame
        warnings.simplefilter("ignore", RuntimeWarning)
        part = np.nanmedian(crops, axis=0)
    unseen = (np.isfinite(crops).sum(axis=0) < 3).astype(np.uint8)
    part = np.where(unseen > 0, background[sy0:sy1, sx0:sx1], np.nan_to_num(part)).round().clip(0, 255).astype(np.uint8)
    clear[sy0:sy1, sx0:sx1] = part
    if unseen.any():
        hole = np.zeros((h, w), np.uint8)
        hole[sy0:sy1, sx0:sx1] = unseen
        clear = cv2.inpaint(clear, hole, 3, cv2.INPAINT_TELEA)
    return clear


def _find(frame, template, weight, ref, guess, reach, angle=0.0):
    """The template's best place in the frame: (place (2,), standard error, correlation, the
    frame's patch aligned there, angle) or None (angle: the template's turn in the frame before)."""
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
    # the predicted place is refined first: where something passes behind the object, the
    # correlation's peak may lie on that instead, and the object where it should be still scores
    # best; where it scores well, the correlation over the window is not needed
    best = _refine(frame, template, weight, ref, np.asarray(guess, dtype=np.float64), angle) if guess is not None else None
    if best is not None and best[2] >= GOOD:
        return best
    window = frame[y0:y1, x0:x1]
    tm = _turned(template, ref, angle) if abs(angle) > 0.02 else template
    wm = _turned(weight, ref, angle) if abs(angle) > 0.02 else weight
    corr, f = _correlation(window, tm, wm)
    # the correlation's best peak is refined and scored; where that is poor, the next best peaks
    # too (a dark leg correlates with a can's edges better than the can half hidden behind it)
    spread = max(3, min(th, tw) // 2) // f
    for _ in range(PEAKS):
        j = int(np.argmax(corr))
        py, px = divmod(j, corr.shape[1])
        if corr[py, px] <= -1.0:
            break
        found = _refine(frame, template, weight, ref, np.array([x0 + f * px, y0 + f * py], dtype=np.float64) + ref, angle)
        if found is not None and (best is None or found[2] > best[2]):
            best = found
        if best is not None and best[2] >= GOOD:
            break
        corr[max(py - spread, 0):py + spread + 1, max(px - spread, 0):px + spread + 1] = -1.0
    return best


COARSE = 32  # a template this many pixels across or more is searched for at half the resolution


def _correlation(window, template, weight) -> tuple[np.ndarray, int]:
    """The template's normalised correlation at every place in the window, and the factor f its grid
    is coarser than the frame's: a large template (COARSE pixels across or more: a ball in a 1080p
    clip) is matched on both halved, a sixteenth of the work, its peak within a pixel of the full
    resolution's, which the Gauss-Newton refinement from there finds (matching at full resolution
    was 21 s of a 49 s read of the 1920x1080 bouncing ball)."""
    f = 2 if min(template.shape) >= COARSE and min(window.shape) >= 2 * COARSE else 1
    if f > 1:
        half = lambda a: cv2.resize(a, (a.shape[1] // f, a.shape[0] // f), interpolation=cv2.INTER_AREA)
        window, template, weight = half(window), half(template), half(weight)
    corr = cv2.matchTemplate(window, template, cv2.TM_CCORR_NORMED if _flat(template) else cv2.TM_CCOEFF_NORMED,
                             mask=weight)
    return np.nan_to_num(corr, nan=-1.0, posinf=-1.0, neginf=-1.0), f


def _turned(image, ref, angle):
    """The template turned by angle (radians) about its reference point."""
    m = cv2.getRotationMatrix2D((float(ref[0]), float(ref[1])), -math.degrees(angle), 1.0)
    return cv2.warpAffine(image, m, (image.shape[1], image.shape[0]), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _flat(template: np.ndarray) -> bool:
    return float(template.std()) < 1e-3


def _sample(frame, place, angle, ref, shape):
    """The frame read on the template's grid placed with its reference point at place and turned by angle."""
    th, tw = shape
    c, s = math.cos(angle), math.sin(angle)
    # template pixel (u, v) -> frame (place + R (u - ref))
    m = np.array([[c, -s, place[0] - c * ref[0] + s * ref[1]],
                  [s, c, place[1] - s * ref[0] - c * ref[1]]], dtype=np.float64)
    return cv2.warpAffine(frame, m, (tw, th), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)


def _refine(frame, template, weight, ref, place, angle=0.0):
    """Gauss-Newton on the template's place and turn (with a gain and an offset for the light),
    robustly weighted; (place, standard error, weighted correlation, aligned patch, angle) or None.
    The steps are taken in the template's own frame (forward composition): a shift d and a turn
    da move the frame's point of template pixel u to place + R(angle) (R(da) (u - ref) + d)."""
    th, tw = template.shape
    t_vec = template.ravel().astype(np.float64)
    wgt = weight.ravel().astype(np.float64)
    vs, us = np.mgrid[0:th, 0:tw].astype(np.float64)
    u, v = (us - ref[0]).ravel(), (vs - ref[1]).ravel()
    robust = np.ones_like(wgt)
    edges = _edge_masks(weight)  # the template's, the same at every step
    place = np.asarray(place, dtype=np.float64).copy()
    a = None
    s2 = 0.0
    for _ in range(STEPS):
        patch = _sample(frame, place, angle, ref, template.shape)
        gy, gx = np.gradient(patch.astype(np.float64))
        gx, gy = gx.ravel(), gy.ravel()
        p = patch.ravel().astype(np.float64)
        jac = np.column_stack([gx, gy, gy * u - gx * v, -t_vec, -np.ones_like(t_vec)])
        ww = wgt * robust
        a = jac.T @ (jac * ww[:, None])
        try:
            d = np.linalg.solve(a, -(jac.T @ (ww * p)))
        except np.linalg.LinAlgError:
            return None
        resid = p + jac @ d  # the residual after the step, to first order
        s2 = float((ww * resid ** 2).sum() / max(ww.sum() - 5, 1.0))
        # the robust scale from the median misfit of the weighted pixels, not their RMS: a leg
        # behind the object's edge misfits by the whole contrast and would widen an RMS scale
        scale = max(1.4826 * float(np.median(np.abs(resid[wgt > 0]))), 1e-3)
        robust = 1.0 / (1.0 + (resid / (3.0 * scale)) ** 2)
        robust = _edges_as_around(robust, edges)
        step = np.clip(d[:2], -1.0, 1.0)  # the linearisation holds within about a pixel
        turn = float(np.clip(d[2], -0.05, 0.05))
        c, s = math.cos(angle), math.sin(angle)
        place = place + np.array([c * step[0] - s * step[1], s * step[0] + c * step[1]])
        angle += turn
        if float(np.abs(step).max()) < 1e-3 and abs(turn) < 1e-4:
            break
    try:
        cov = np.linalg.inv(a) * s2
        se = math.sqrt(max(float(cov[0, 0] + cov[1, 1]), 0.0))
    except np.linalg.LinAlgError:
        se = math.inf
    patch = _sample(frame, place, angle, ref, template.shape).astype(np.float32)
    return place, se, _score(patch, template, weight), patch, angle


def _edge_masks(weight) -> tuple[np.ndarray, np.ndarray] | None:
    """The template's outer ring of surroundings (beyond the edge's blur) and its object's deep
    inside (EDGE pixels from the outline), (h, w) bool each, for _edges_as_around; None where the
    template has no outer ring."""
    inside = (weight >= 1.0).astype(np.uint8)
    outer = (weight > 0) & (cv2.dilate(inside, np.ones((3, 3), np.uint8)) == 0)
    if not outer.any():
        return None
    deep = cv2.erode(inside, np.ones((2 * EDGE + 1, 2 * EDGE + 1), np.uint8)) > 0
    return outer, deep


def _edges_as_around(robust, edges):
    """The robust weights (flat, one per template pixel) with each pixel of the object's edge
    trusted no more than the outer ring of surroundings next to it (edges: _edge_masks). An edge
    pixel mixes the object with what lies behind it; where that changed (a dark leg behind the
    can's edge, where the template had the wall) it misfits by only a share of the change, too
    little to be set aside on its own, and every one of them pulls the same way. The outer ring,
    MARGIN pixels out, says so whatever the template's misplacement: it lies beyond the edge's blur."""
    if edges is None:
        return robust
    outer, deep = edges
    img = robust.reshape(outer.shape)
    reach = 2 * EDGE + 1  # the outer ring's pixels reach the object's first row of pixels
    around = cv2.erode(np.where(outer, img, 1.0).astype(np.float32), np.ones((reach, reach), np.uint8))
    return np.where(deep, img, np.minimum(img, around)).ravel().astype(robust.dtype)


def _score(patch, template, weight) -> float:
    """How well the patch shows the template's object: 1 less the median misfit (after a gain and
    an offset fitted on the object) over the object's contrast with its surroundings, of the
    object's inner pixels and of the ring around it, not of its edge (an edge pixel mixes in
    whatever passes behind). Quantiles, not means: part of the object may be covered, or its label
    turned, or legs may pass behind one side of it, and it is still there."""
    inside = weight >= 1.0
    core = cv2.erode(inside.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    if core.sum() < 4:
        core = inside
    ring = (weight > 0) & ~inside
    # the gain and the offset from the core (an edge pixel mixes in what passes behind)
    t_in, p_in = template[core].astype(np.float64), patch[core].astype(np.float64)
    design = np.column_stack([t_in, np.ones_like(t_in)])
    (gain, offset), *_ = np.linalg.lstsq(design, p_in, rcond=None)
    # the light changes the object's look a little; a flat patch (gain 0) is not the object
    gain = float(np.clip(gain, 0.8, 1.25))
    offset = float(np.median(p_in - gain * t_in))
    # the object's inner pixels and the outer ring around it: legs behind the can change a part
    # of the ring, a dark patch that is not the can changes all of it
    outer = ring & (cv2.dilate(inside.astype(np.uint8), np.ones((3, 3), np.uint8)) == 0)
    contrast = abs(float(np.median(template[inside])) - float(np.median(template[ring]))) if ring.any() else 0.0
    contrast = max(contrast, float(template[weight > 0].std()), 1.0)
    # ... and an offset of at most OFFSET of the object's contrast: a dark leg behind a plain gray
    # can matches its inside once shifted by their whole difference in brightness
    offset = float(np.clip(offset, -OFFSET * contrast, OFFSET * contrast))
    # each part on its own: a flat patch matches a plain object's inside, and only its ring says
    # that it is not the object
    # the core by its median, the ring by its lower quartile: what passes behind the object covers
    # a part of its ring (a leg one side of the can), a patch that is not the object misses all of it
    expected = gain * template + offset
    misfit = float(np.median(np.abs(patch[core] - expected[core]))) if core.any() else 0.0
    if outer.any():
        # a ring pixel is the object's surroundings where it shows what surrounded it in the
        # template, or anything that differs from the object's inside by its whole contrast: a
        # leg wider than the can behind it covers all of its ring, and the can stands out of it
        level = float(np.median(patch[core])) if core.any() else float(np.median(patch[inside]))
        ring_miss = np.minimum(np.abs(patch[outer] - expected[outer]),
                               np.maximum(contrast - np.abs(patch[outer] - level), 0.0))
        misfit = max(misfit, float(np.quantile(ring_miss, RING_QUANTILE)))
    return float(1.0 - misfit / contrast)


SWITCH_AREA = 2.0  # a switch: the path's object changes its area by this factor from one frame to the next ...
SWITCHES = 3          # the change detector's path is set aside where it switches at least this many times
SAME = 0.5         # ... and is not taken where it stays within the object's size of the detector's path in this share
SEEN = 0.9         # ... and the object tracker places the object in at least this share of the frames (the
                   # position observation reads no more than a tenth of them from their neighbours)
STEADIER = 2.0     # where both follow the same object, the object tracker's path is taken where it scatters this many times less
PROBE = 40         # ... judged first on this many consecutive frames (following the whole clip costs more than reading it)
CHANGE = "the change from the static scene"  # the detector's path, as the track's line names it


def switches(path: np.ndarray, area: np.ndarray) -> int:
    """How often a path (T, 2; NaN where unseen) goes from one moving thing to another: its region's
    area (T,) changes by SWITCH_AREA or more from one seen frame to the next while it steps farther
    than the smaller region's size. An object that moves keeps its size from frame to frame (the
    real pendulums: never); a path that takes legs walking behind a can for it does not."""
    seen = np.isfinite(path[:, 0]) & np.isfinite(area)
    p, a = path[seen], np.maximum(area[seen], 1.0)
    if len(p) < 2:
        return 0
    grows = np.abs(np.diff(np.log(a))) >= math.log(SWITCH_AREA)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    return int((grows & (step > np.sqrt(np.minimum(a[1:], a[:-1])))).sum())


def scatter(path: np.ndarray) -> float:
    """How far a path (T, 2; NaN where unseen) scatters from frame to frame about a smooth motion,
    in pixels: the median length of its third differences over runs of four placed frames, over
    sqrt(20) (a third difference of independent errors has 20 times their variance; a swing, a fall
    or a bounce between frames adds little to it). NaN where under 8 runs have it."""
    third = np.diff(path, n=3, axis=0)
    ok = np.isfinite(third[:, 0]) & np.isfinite(third[:, 1])
    if ok.sum() < 8:
        return math.nan
    return float(np.median(np.linalg.norm(third[ok], axis=1)) / math.sqrt(20.0))


def choose(stack: np.ndarray, paths: np.ndarray, area: np.ndarray,
           found: Followed | None = None) -> tuple[np.ndarray, str, Followed | None]:
    """The track the reader takes, and one line on why: the change detector's strongest path
    (paths: (n, T, 2), fitode.video.track.measure_paths; area: (T,) its region's pixels per frame)
    where it does not switch from one moving thing to another (fewer than SWITCHES switches) and
    the object tracker does not follow that object more steadily (_steadier); else the object
    tracker's (follow_best, seeded by the detector's paths), hidden frames NaN, where it places the
    object in at least SEEN of the frames and follows another thing than the detector's path
    (within the object's size in under SAME of them: a small object whose region flickers switches
    too, and both follow it): something else changes more than the object for a while (legs
    walking behind a can) and the detector's path goes from one to the other. found: the object
    tracker's result where the caller has it. Returns the path (T, 2), the line, and the object
    tracker's result where its path was taken (else None)."""
    change = CHANGE
    n = switches(paths[0], area)
    if n < SWITCHES:
        return _steadier(stack, paths[0], found, f"{change} (its path switches between moving things {n} time{'s' if n != 1 else ''}: under {SWITCHES}")
    found = follow_best(stack, paths) if found is None else found
    if found is None:
        return paths[0], f"{change} (its path switches between moving things {n} times, but the object tracker found nothing to follow)", None
    seen = float(np.isfinite(found.xy[:, 0]).mean())
    if seen < SEEN:
        return paths[0], (f"{change} (its path switches between moving things {n} times, but the object tracker placed the object in only "
                          f"{100 * seen:.0f}% of the frames)"), None
    same = _same(paths[0], found)
    if same >= SAME:
        return _steadier(stack, paths[0], found, (f"{change} (its path switches between moving things {n} times, but the "
                                                  f"object tracker follows the same object: within its size in {100 * same:.0f}% of the frames"))
    return found.xy, f"{found.note}, not {change}: its path switches between moving things {n} times", found


def _same(path: np.ndarray, found: Followed) -> float:
    """The share of the frames both place in which the object tracker's place lies within the
    object's size of the detector's path, once their median offset is taken out."""
    both = np.isfinite(path[:, 0]) & np.isfinite(found.xy[:, 0])
    if not both.any():
        return 0.0
    d = path[both] - found.xy[both]
    return float((np.linalg.norm(d - np.median(d, axis=0), axis=1) <= math.sqrt(found.area)).mean())


def _steadier(stack: np.ndarray, path: np.ndarray, found: Followed | None,
              why: str) -> tuple[np.ndarray, str, Followed | None]:
    """The detector's path (T, 2) where it does not switch, unless the object tracker follows the
    same object with STEADIER times less scatter from frame to frame: the detector's centroid weighs
    each pixel by its change, which moves with what lies behind the object and with its shading
    (a shaded ball that falls past a textured wall: 0.1 pixel of scatter and a pixel of offset,
    where the tracker's place scatters by 0.02), and on an object that covers its own place in the
    static scene it is the centroid of a crescent. Judged first on PROBE frames (where the caller
    has no object tracker's result), then on the whole clip. why: the line's start."""
    keep = f"{why})"
    if found is None:
        seen = np.flatnonzero(np.isfinite(path[:, 0]))
        if len(seen) < 8:
            return path, keep, None
        middle = int(np.median(seen))
        a = max(0, min(middle - PROBE // 2, len(path) - PROBE))
        stretch = slice(a, a + PROBE)
        _, background, noise = static_scene(stack)
        probe = follow_object(stack[stretch], path[stretch], background, noise)
        if probe is None or not scatter(probe.xy) * STEADIER <= scatter(path[stretch]):
            return path, keep, None
        found = follow_object(stack, path, background, noise)
    if found is None:
        return path, f"{why}; the object tracker found nothing to follow)", None
    seen = float(np.isfinite(found.xy[:, 0]).mean())
    if seen < SEEN:
        return path, f"{why}; the object tracker placed it in only {100 * seen:.0f}% of the frames)", None
    if _same(path, found) < SAME:
        return path, f"{why}; the object tracker follows another object)", None
    mine, theirs = scatter(found.xy), scatter(path)
    if not mine * STEADIER <= theirs:
        return path, f"{why}; the object tracker follows it with {mine:.2g} px of scatter from frame to frame, the change with {theirs:.2g})", None
    return found.xy, (f"{found.note}, not {CHANGE}: both follow the same object, with {mine:.2g} px of scatter from "
                      f"frame to frame against the change's {theirs:.2g}"), found
