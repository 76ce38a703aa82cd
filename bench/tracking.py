"""tracking: how far the track is from where the object really is, in pixels.

Generated scenes whose object's true place is known in every frame (the camera model of
fitode's scenes: blur, noise, sRGB, JPEG; 320x240 unless said):

    can     a can on a spring that bounces, sways and turns (its label goes round), two dark legs
            walking back and forth behind it (`fitode synth scene spring --param legs=2
            --param distractors=0`, w2 18, 30 fps, 8 s); truth: the can's centre
    hand    a ball held by a hand, lifted and let go; it falls, the hand pulls away (60 fps)
    large   a block a third of the frame wide, printed with bands in two random colours and a
            darker frame, swinging sideways (30 fps, 8 s)
    water   a tank draining (h' = -k sqrt(h)), its width, its back's grey and its water's colour
            random; truth: the water line's row (30 fps, 8 s)
    small   a ball 2 pixels across on a pendulum's arc (30 fps, 6 s)

and the shared real pendulums and the drop (../shared/realvideos) against bench/realclips.py's
colour tracker (its functions: the HSV blob's centroid; the drop on the frames of its fall, from
the release to the floor, as realclips.py fits it). The colour tracker sees only a part of
some objects (the bob's blue lower half), so on the real clips the table gives the RMS difference
after their median offset is taken out, on the frames both follow, beside the raw one. That offset
does not take out all of it on the bob: the blue half's centroid lies about 12 px below the ball's
centre (the object tracker's point on the clip's first 300 frames: 12.1 px above it, the median)
and turns about it with the string, so their difference across the swing runs from -3.2 to +0.6 px
in x; no reading of the ball's centre comes within 1 px of this reference. On the drop the
reference is the ball's: the change detector's region takes in the hand that lets it go on the
fall's first 20 frames (7.8 px RMS, 13.3 at most) and follows the ball within 0.53 px on the
other 40.

Each track is read by the change detector (fitode.video.track.measure, the reader's until now), by
the object tracker (fitode.video.follow) seeded by it, and as the reader takes it
(fitode.video.track.place: the detector's unless its path switches between moving things or the
object tracker follows the same object more steadily, fitode.video.follow.choose; the water line
where the detector's path is a band of water,
fitode.video.waterline); the table gives the RMS error and the largest, the frames each could
not place, and the constant the track leads to (a damped sine's w0^2 for the oscillations, the
fall's g in px/s^2, Torricelli's k in px^0.5/s), fitted to the track as realclips.py fits its own.

    python bench/tracking.py                 # every scene and clip (a few minutes)
    python bench/tracking.py --scenes can,small --no-real

Prints one table; writes <out>/tracking.json.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402
import realclips as rc  # noqa: E402

SIZE = (240, 320)  # (height, width)


# ----------------------------------------------------------------------------- generated scenes
def _camera(seed: int, h: int, w: int):
    from fitode.synth.scenes import _Sensor

    return _Sensor(np.random.default_rng([seed, 29]), (h, w, 3), 1.0, 0.7, 85)


def _film(background: np.ndarray, draw: Callable, n: int, seed: int) -> np.ndarray:
    """Gray uint8 frames (n, H, W) of draw(canvas, i) painted over the background, through the camera."""
    import cv2
    from fitode.synth import render as R

    h, w = background.shape[:2]
    sensor = _camera(seed, h, w)
    out = np.empty((n, h, w), np.uint8)
    for i in range(n):
        cv = R.Canvas(background.copy(), 4)
        draw(cv, i)
        out[i] = cv2.cvtColor(sensor(cv.image), cv2.COLOR_RGB2GRAY)
    return out


def _wall(rng, h, w):
    from fitode.synth.scenes import _wall as wall

    return wall(rng, h, w, base=(0.74, 0.72, 0.7), light_from=(0.7, 0.0))


def scene_can(seed: int) -> dict[str, Any]:
    import cv2
    from fitode.synth.scenes import scene

    v = scene("spring", 18.0, seed=seed, fps=30.0, duration=8.0, size=SIZE, legs=2, distractors=0)
    gray = np.stack([cv2.cvtColor(f, cv2.COLOR_RGB2GRAY) for f in v.frames])
    return {"frames": gray, "truth": v.pixels, "dt": v.dt, "kind": "oscillation", "axis": 1,
            "constant": ("w2", 18.0)}


def scene_hand(seed: int) -> dict[str, Any]:
    from fitode.synth import render as R

    rng = np.random.default_rng([seed, 3])
    h, w = SIZE
    fps, release, fall = 60.0, 0.5, 0.55
    n = int(round((release + fall + 0.2) * fps))
    t = np.arange(n) / fps
    drop = rng.uniform(120, 160)  # pixels fallen in `fall` seconds
    g = 2 * drop / fall ** 2
    x0, y0, r = rng.uniform(0.35, 0.65) * w, 0.2 * h, 7.0
    lift = 8.0 * np.sin(np.clip(t / release, 0, 1) * np.pi / 2)  # raised a little before it is let go
    ty = np.where(t < release, y0 - lift, y0 - lift[-1] + 0.5 * g * np.clip(t - release, 0, fall) ** 2)
    truth = np.stack([np.full(n, x0), ty], axis=1) - 0.5
    hand_x = x0 + np.where(t < release, 0.0, 160.0 * (t - release))
    hand_y = np.where(t < release, ty - 1.2 * r, y0 - lift[-1] - 1.2 * r - 60.0 * (t - release))
    skin = np.asarray((0.85, 0.6, 0.48), np.float32)

    def draw(cv, i):
        bx, by = truth[i] + 0.5
        cv.paint(R.circle(bx, by, r), R.sphere_shade(bx, by, r, (0.75, 0.2, 0.15)), (bx - r, by - r, bx + r, by + r))
        hx, hy = hand_x[i], hand_y[i]
        cv.paint(R.box(hx, hy - 14, 16, 14, radius=6), skin, (hx - 20, hy - 32, hx + 20, hy + 4))
        for k in (-1, 1):  # two fingers round the ball while it is held
            cv.paint(R.segment(hx + k * 9, hy - 4, hx + k * 9, hy + 9, 3.0), skin * 0.95,
                     (hx + k * 9 - 5, hy - 8, hx + k * 9 + 5, hy + 14))

    frames = _film(_wall(rng, h, w), draw, n, seed)
    keep = (t >= release) & (t <= release + fall)  # the fall
    return {"frames": frames, "truth": truth, "dt": 1 / fps, "kind": "fall", "axis": 1, "fit": keep,
            "constant": ("g_px", g)}


def scene_large(seed: int) -> dict[str, Any]:
    from fitode.synth import render as R

    rng = np.random.default_rng([seed, 5])
    h, w = SIZE
    fps, n = 30.0, 240
    t = np.arange(n) / fps
    w0, rate = rng.uniform(2.5, 3.5), 0.05
    amp = 0.16 * w
    cx = w / 2 + amp * np.exp(-rate * t) * np.cos(np.sqrt(w0 ** 2 - rate ** 2) * t)
    cy = np.full(n, 0.55 * h)
    truth = np.stack([cx, cy], axis=1) - 0.5
    half_w, half_h = w / 6, 0.18 * h
    # two band colours at random, each far enough from the wall's grey that the block's ends show
    # (a band the wall's colour at its end leaves no tracker a way to see where the block ends)
    luma = np.array([0.299, 0.587, 0.114])
    bands = []
    while len(bands) < 2:
        c = rng.uniform(0.05, 0.95, 3).astype(np.float32)
        if abs(float(luma @ c) - 0.72) >= 0.15 and all(abs(float(luma @ (c - b))) >= 0.15 for b in bands):
            bands.append(c)

    def draw(cv, i):
        x, y = cx[i], cy[i]

        def body(xx, yy):  # a box with a printed pattern: bands and a darker frame
            u, v = (xx - x) / half_w, (yy - y) / half_h
            band = (0.5 + 0.5 * np.sign(np.sin(3 * np.pi * u + 2 * v)))[..., None]
            col = bands[0] * (1 - band) + bands[1] * band
            edge = np.minimum(half_w - np.abs(xx - x), half_h - np.abs(yy - y)) < 3.0
            return np.where(edge[..., None], 0.55 * col, col * (0.8 + 0.2 * (1 - v * v))[..., None])
        cv.paint(R.box(x, y, half_w, half_h, radius=3), body, (x - half_w - 2, y - half_h - 2, x + half_w + 2, y + half_h + 2))

    return {"frames": _film(_wall(rng, h, w), draw, n, seed), "truth": truth, "dt": 1 / fps, "kind": "oscillation",
            "axis": 0, "constant": ("w0^2", w0 ** 2)}


def scene_water(seed: int) -> dict[str, Any]:
    from fitode.synth import render as R

    rng = np.random.default_rng([seed, 7])
    h, w = SIZE
    fps, n = 30.0, 240
    t = np.arange(n) / fps
    bottom, h0 = rng.uniform(0.8, 0.92) * h, rng.uniform(0.45, 0.6) * h
    k = 2 * (math.sqrt(h0) - math.sqrt(0.25 * h0)) / t[-1]  # drains to a quarter
    level = bottom - (math.sqrt(h0) - k * t / 2) ** 2
    middle, half = rng.uniform(0.35, 0.65) * w, rng.uniform(0.06, 0.16) * w  # a narrow tube or a wide tank
    x0, x1 = middle - half, middle + half
    # the tank's back and the water in any colour, the water lighter or darker than the back
    back = np.full(3, rng.uniform(0.3, 0.85), np.float32)
    luma = np.array([0.299, 0.587, 0.114])
    water = rng.uniform(0.05, 0.95, 3).astype(np.float32)
    while abs(float(luma @ water) - float(back[0])) < 0.2:
        water = rng.uniform(0.05, 0.95, 3).astype(np.float32)
    truth = np.stack([np.full(n, (x0 + x1) / 2), level], axis=1) - 0.5
    bg = _wall(rng, h, w)
    glass = R.Canvas(bg, 4)
    glass.paint(R.box((x0 + x1) / 2, (bottom + 0.15 * h) / 2, (x1 - x0) / 2 + 3, (bottom - 0.15 * h) / 2 + 3, radius=3),
                (0.55, 0.58, 0.6), (x0 - 5, 0.15 * h - 5, x1 + 5, bottom + 5))
    glass.paint(R.box((x0 + x1) / 2, (bottom + 0.15 * h) / 2, (x1 - x0) / 2, (bottom - 0.15 * h) / 2, radius=2),
                back, (x0 - 2, 0.15 * h - 2, x1 + 2, bottom + 2))

    def draw(cv, i):
        top = level[i]
        cv.paint(R.intersect(R.box((x0 + x1) / 2, (bottom + 0.15 * h) / 2, (x1 - x0) / 2, (bottom - 0.15 * h) / 2),
                             R.half_plane(0.0, -1.0, 0.0, top)),
                 water, (x0 - 1, top - 1, x1 + 1, bottom + 1))

    return {"frames": _film(glass.image, draw, n, seed), "truth": truth, "dt": 1 / fps, "kind": "drain", "axis": 1,
            "bottom": bottom - 0.5, "constant": ("k_px", k)}


def scene_small(seed: int) -> dict[str, Any]:
    from fitode.synth import render as R

    rng = np.random.default_rng([seed, 11])
    h, w = SIZE
    fps, n = 30.0, 180
    t = np.arange(n) / fps
    length, w0, amp = 400.0, rng.uniform(2.0, 3.0), rng.uniform(0.12, 0.18)
    theta = amp * np.exp(-0.04 * t) * np.cos(w0 * t)
    px, py = w / 2, 0.6 * h - length
    bx, by = px + length * np.sin(theta), py + length * np.cos(theta)
    truth = np.stack([bx, by], axis=1) - 0.5

    def draw(cv, i):
        cv.paint(R.circle(bx[i], by[i], 1.0), (0.1, 0.1, 0.12), (bx[i] - 2, by[i] - 2, bx[i] + 2, by[i] + 2))

    return {"frames": _film(_wall(rng, h, w), draw, n, seed), "truth": truth, "dt": 1 / fps, "kind": "oscillation",
            "axis": 0, "constant": ("w0^2", w0 ** 2)}


SCENES: dict[str, Callable[[int], dict[str, Any]]] = {
    "can": scene_can, "hand": scene_hand, "large": scene_large, "water": scene_water, "small": scene_small}
LIMIT = {"small": 1.0}  # the RMS error a scene's track must stay within (px); 0.3 elsewhere
REAL = ("pendulum_bob_L062.mp4", "pendulum_apple_damped.mov", "pendulum_ornament_L170.mp4",
        "freefall_balldrop_slowmo120.mp4")


# ----------------------------------------------------------------------------- trackers
def track_change(frames: np.ndarray) -> np.ndarray:
    """The change detector's path (the reader's track until now)."""
    from fitode.video.track import measure

    return measure(frames)[0]


def track_object(frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """The object tracker seeded by the change detector's paths, and the path the reader takes
    (fitode.video.track.place: the detector's, the object tracker's or a water line) with its note,
    worked out as the reader does (it follows the detector's own path where that does not switch)."""
    from fitode.video.follow import follow_best
    from fitode.video.track import MAX_OBJECTS, measure_paths, place

    paths, areas = measure_paths(frames, MAX_OBJECTS, per_frame=True)
    found = follow_best(frames, paths)
    chosen, how, _, _ = place(frames, paths, areas)
    return (np.full((len(frames), 2), np.nan) if found is None else found.xy), chosen, how


def errors(path: np.ndarray, truth: np.ndarray, axis: int | None = None, offset: bool = False) -> dict[str, Any]:
    """RMS and largest distance (px) on the frames both have (one coordinate where axis is given),
    after the median offset where offset."""
    both = np.isfinite(path[:, 0]) & np.isfinite(truth[:, 0])
    if not both.any():
        return {"rms": math.nan, "max": math.nan, "frames": 0, "missing": int(np.isfinite(truth[:, 0]).sum())}
    d = path[both] - truth[both]
    if offset:
        d = d - np.median(d, axis=0)
    d = np.abs(d[:, axis]) if axis is not None else np.linalg.norm(d, axis=1)
    return {"rms": float(np.sqrt(np.mean(d ** 2))), "max": float(d.max()), "frames": int(both.sum()),
            "missing": int((np.isfinite(truth[:, 0]) & ~np.isfinite(path[:, 0])).sum())}


def constant(sc: dict[str, Any], path: np.ndarray) -> float:
    """The scene's constant read from a track as realclips.py reads its own."""
    t = np.arange(len(path)) * sc["dt"]
    use = np.isfinite(path[:, 0]) & sc.get("fit", np.ones(len(path), bool))
    if use.sum() < 8:
        return math.nan
    x = path[use, sc["axis"]]
    if sc["kind"] == "oscillation":
        return rc.fit_damped_sinusoid(t[use], x)["w0"] ** 2
    if sc["kind"] == "fall":
        return rc.parabola_fit(t[use], x)["g_px"]
    coef, _, _ = rc.polyfit_se(t[use], np.sqrt(np.maximum(sc["bottom"] - x, 0.0)), 1)
    return -2 * float(coef[1])


# ----------------------------------------------------------------------------- runs
def run_scene(name: str, seed: int) -> list[dict[str, Any]]:
    sc = SCENES[name](seed)
    truth = sc["truth"]
    label, value = sc["constant"]
    axis = 1 if sc["kind"] == "drain" else None  # a level is its row
    rows = []
    obj, chosen, how = track_object(sc["frames"])
    for tracker, path in (("change", track_change(sc["frames"])), ("object", obj), ("choice", chosen)):
        e = errors(path, truth, axis)
        c = constant(sc, path)
        rows.append({"source": f"{name} (seed {seed})", "tracker": tracker, **e, "how": how if tracker == "choice" else "",
                     "constant": label, "value": c, "truth": value, "off": (c - value) / value,
                     "limit": LIMIT.get(name, 0.3)})
    return rows


def run_real(name: str, folder: Path) -> list[dict[str, Any]]:
    import cv2

    path = folder / name
    clip = rc.CLIPS[name]
    if clip.kind == "freefall":  # the fall, from the release to the floor, as realclips.py fits it
        m = rc.measure_freefall(path, clip)
        frames, colour = m["frames"], m["track"]
        keep = np.zeros(len(frames), bool)
        keep[m["fit"]["start_frame"]:m["fit"]["end_frame"] + 1] = True
    else:
        frames = list(rc.read_frames(path))
        colour = rc.track_colour(frames, clip.hsv)
        keep = np.ones(len(frames), bool)
    truth = np.stack([colour["x"], colour["y"]], axis=1)
    truth[~keep] = np.nan
    gray = np.stack([cv2.cvtColor(f, cv2.COLOR_BGR2GRAY) for f in frames])
    del frames
    rows = []
    obj, chosen, how = track_object(gray)
    for tracker, p in (("change", track_change(gray)), ("object", obj), ("choice", chosen)):
        e = errors(p, truth, offset=True)
        raw = errors(p, truth)
        rows.append({"source": name, "tracker": tracker, **e, "raw_rms": raw["rms"], "limit": 1.0,
                     "how": how if tracker == "choice" else "",
                     "constant": "", "value": math.nan, "truth": math.nan, "off": math.nan})
    return rows


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=None)
    parser.add_argument("--scenes", default=",".join(SCENES), help="generated scenes, comma-separated")
    parser.add_argument("--seeds", default="1", help="seeds of the generated scenes, comma-separated")
    parser.add_argument("--clips", default=",".join(REAL), help="shared real clips, comma-separated")
    parser.add_argument("--no-real", action="store_true", help="only the generated scenes")
    parser.add_argument("--dir", default=str(rc.CLIP_DIR), help="the real clips' folder")


def run(args: argparse.Namespace) -> int:
    names = ["hand"] if args.quick else bc.pick(args.scenes, list(SCENES), "--scenes")
    seeds = [int(s) for s in str(args.seeds).split(",") if s.strip()]
    if args.quick:  # one short generated scene, no real clip
        args.no_real, seeds = True, seeds[:1]
    t_all = time.perf_counter()
    rows: list[dict[str, Any]] = []
    for name in names:
        for seed in seeds:
            bc.progress(f"{name} seed {seed} ...")
            rows += run_scene(name, seed)
    skips: list[str] = []
    if not args.no_real:
        found, skips = rc.find_clips(Path(args.dir), bc.pick(args.clips, list(REAL), "--clips"))
        for s in skips:
            bc.progress(s)
        for name, _ in found:
            bc.progress(f"{name} ...")
            rows += run_real(name, Path(args.dir))
    record = {"benchmark": "tracking", "rows": rows, "skips": skips, "wall_s": time.perf_counter() - t_all,
              "machine": bc.machine_info(), "git": bc.git_state()}
    return bc.report_and_write(record, args.out, "tracking", print_report)


def print_report(record: dict[str, Any]) -> None:
    table = []
    for r in record["rows"]:
        ok = r["rms"] is not None and math.isfinite(r["rms"]) and r["rms"] <= r["limit"]
        table.append({"source": r["source"], "tracker": r["tracker"], "rms": bc.num(r["rms"]),
                      "max": bc.num(r["max"]), "raw": bc.num(r.get("raw_rms")) if r.get("raw_rms") is not None else "",
                      "frames": str(r["frames"]), "missing": str(r["missing"]),
                      "within": f"{'yes' if ok else 'NO'} ({r['limit']:g})",
                      "constant": f"{r['constant']} {bc.num(r['value'], 4)} ({bc.pct(r['off'])})" if r["constant"] else ""})
    print(bc.format_table(table, [("source", "source"), ("tracker", "tracker"), ("RMS px", "rms"), ("max px", "max"),
                                  ("raw RMS", "raw"), ("frames", "frames"), ("unplaced", "missing"),
                                  ("within", "within"), ("constant from the track", "constant")],
                          title="tracking: the track against the true place (real clips: against the colour "
                                "tracker, median offset out)"))
    for s in record.get("skips", []):
        print(s)
    print(bc.ran_on(record))


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
