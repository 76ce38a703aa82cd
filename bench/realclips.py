"""realclips: ground truth for the real camera clips of ../shared/realvideos, measured with a colour tracker and a curve fit.

The clips (see ../shared/realvideos/SOURCES.md; they are read from there and never copied into the
repository, several have no licence) come with few or unreliable stated parameters, so this
benchmark measures the truth the way a careful user would: an HSV colour threshold picks the
moving object in every decoded frame (the largest connected blob of the clip's colour inside the
clip's region), and the same equation fitode fits is fitted to that track with scipy's least
squares. Optionally (--fitode) it also runs the documented fitode command for each clip and
puts fitode's estimate beside the tracker's.

Pendulums (pendulum_bob_L062.mp4, pendulum_apple_damped.mov, pendulum_ornament_L170.mp4)
    Track: centroid of the bob's colour (bob: its blue lower half; apple and ornament: red), every
    decoded frame, t = frame / the frames' stamped rate (the container's where its stamps are
    irregular; the bob clip: only its 1844 decodable frames).
    The (x, y) track is projected onto its main direction of motion (first principal axis) and
    x(t) = A exp(-t/tau) cos(w t + phi) + c is fitted (scipy.optimize.least_squares, the decay
    rate 1/tau as the free parameter; start: w from the FFT peak of the zero-padded track, A, phi
    from a linear fit at that w). The linearised equation theta'' = -g/L theta - zeta theta' has
    exactly that solution with 1/tau = zeta/2 and w^2 = g/L - 1/tau^2, so the reported period is
    the UNDAMPED one, T = 2 pi / w_0 with w_0 = sqrt(w^2 + 1/tau^2), and zeta = 2/tau.
    Standard errors come from the fit's Jacobian (covariance (J^T J)^-1 times the residual
    variance, then the delta method); they assume independent residuals, so they are lower
    bounds. As a check the two halves of the record are fitted separately and their periods
    reported (JSON: T_halves).
    Amplitude: the bob moves on an arc of radius L_px (pixels), so its height along the swing is
    y = y_c + s^2 / (2 L_px) for an excursion s along the main direction; a quadratic fit of the
    perpendicular coordinate against s gives L_px (scale-free, no ruler needed). Where that
    curvature is not significant (under 3 standard errors: small swings) the amplitude is
    reported as unknown and no correction is made. Otherwise theta(t) = asin(A exp(-t/tau)/L_px),
    and because a constant-frequency fit averages the period over the record, the finite-amplitude
    correction uses the mean of theta(t)^2 over the fitted frames: T0 = T / (1 + <theta^2>/16).
    The swing amplitude reported is the largest, theta(t_first).
    Length: L = g T0^2 / (4 pi^2), g = 9.80665; dL/L = 2 dT/T (the amplitude correction's own
    error, a few 0.01 %, is left out). This L is the length of the equivalent simple pendulum,
    the quantity fitode's pendulum L estimates (theta'' = -g/L sin(theta) - zeta theta').

Free fall (freefall_balldrop_slowmo120.mp4, real time 1/120 s per frame: a 120 fps slow-motion clip)
    Track: centroid of the red ball (saturation >= 125 keeps the skin-coloured hand out). The fit
    window runs from the release (the hand lifts the ball slightly and lets go at its highest
    point: the frame of smallest row in 100-129, frame 118 here) while the ball keeps moving down
    and its blob still has at least 100 pixels (motion blur and lighting wash it out towards the
    gap at 173-201). y = y0 + v0 t + g t^2 / 2 is
    fitted in pixels and converted with the ceiling-to-floor scale: the ceiling row is the top
    edge of the cornice and the floor row the carpet's edge, both found as the strongest
    brightness change of the right half's row profile (ceiling: the first row in 20-300 more
    than 15 grey levels off the plain ceiling above; floor: the largest step in the last 250 rows), and
    232 cm / (floor - ceiling) is the scale. Both rows lie in the wall's plane while the ball
    falls somewhat in front of it, so this scale is slightly too large at the ball (perspective);
    the 4 cm ball diameter against the blob's median width over the window is given as a second
    scale (JSON: g_ball_scale), less precise because the blurred, desaturated blob's edges shrink.
    The estimate depends on the window (fits starting later give smaller g, perspective and the
    fingers near the ball at release): the same fit from 8 frames after the release is shown too.

Draining bottle (draining_bottle_hole7mm.mp4, 29.97 fps)
    Track: per frame, the red-dyed water's rows inside the bottle's column (x 360-530): a row is
    water when more than half its pixels are red; the level is the top of the run of water rows
    Bottom row: the 95th percentile of the lowest water row over the frames
    used. Top row: the rim, the first row below 150 whose brightness differs from the wall above
    by more than 5 grey levels. The level is the top of the longest run of water rows (so the red
    jet below the shelf is never taken for the column).
    From t = 3 s (the hand has left) while the column is at least 12 px tall (the last
    millimetres are a meniscus), sqrt(h) = sqrt(h0) - k t / 2 is fitted (straight line in
    sqrt(h)) with h = bottom row - level row in pixels, then in cm with 16.5 cm / (bottom - rim),
    and in sqrt(m)/s (the unit of fitode's torricelli k) as k_cm / 10.
    With --fitode, how far fitode's reading moves (its track.csv's rows, source pixels) against
    this water top on the frames both read is printed under the table: each one's travel and
    their ratio (a reading of the band of change's centroid moves about half as far).

Bouncing ball (bouncing_ball.avi, 29.97 fps)
    Track: the green ball's centroid, frames 63-117. The first flight after the release is cut at
    the first bounce (the lowest point) and y = y0 + v0 t + g t^2 / 2 is fitted; scale 85 px =
    6.87 cm (SOURCES.md: the MATLAB script's 8.5 in is the circumference). fitode is run as a user
    would, on the whole clip with that scale: it finds the release and the flights itself.

    python bench/realclips.py                         # tracker only (about a minute)
    python bench/realclips.py --clips pendulum_bob_L062.mp4,freefall_balldrop_slowmo120.mp4
    python bench/realclips.py --fitode                # also fitode on every clip (minutes each)
    python bench/realclips.py --check-images DIR      # one frame per clip with the detection drawn

Prints one table; writes <out>/realclips.json (every track's fit, the stated values, fitode's
result when run). A missing ../shared/realvideos folder or clip is a skip with a message.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402

G = 9.80665
REPO = Path(__file__).resolve().parent.parent
CLIP_DIR = REPO.parent / "shared" / "realvideos"  # ../shared/realvideos from the repo root

# HSV ranges in OpenCV's units (H 0-180, S and V 0-255); red wraps around H = 0
RED = [((0, 90, 50), (12, 255, 255)), ((160, 90, 50), (180, 255, 255))]
RED_BALL = [((0, 125, 80), (12, 255, 255)), ((160, 125, 80), (180, 255, 255))]
RED_WATER = [((0, 70, 60), (12, 255, 255)), ((160, 70, 60), (180, 255, 255))]
BLUE = [((95, 80, 40), (130, 255, 255))]
GREEN = [((40, 80, 40), (90, 255, 255))]


@dataclass
class Clip:
    name: str
    kind: str  # pendulum | freefall | bottle | bounce
    hsv: list
    fps: float | None = None  # real frame rate when it differs from the container's
    stated: dict[str, Any] = field(default_factory=dict)  # quantity -> (value or None, text)
    fitode_args: list[str] = field(default_factory=list)
    fitode_param: str = ""
    note: str = ""


CLIPS: dict[str, Clip] = {c.name: c for c in [
    Clip("pendulum_bob_L062.mp4", "pendulum", BLUE,
         stated={"L": (0.62, "0.62 m rope (+ bob radius)")},
         fitode_args=["--system", "pendulum"], fitode_param="L"),
    Clip("pendulum_apple_damped.mov", "pendulum", RED,
         stated={"L": (None, "none stated")},
         fitode_args=["--system", "pendulum"], fitode_param="L"),
    Clip("pendulum_ornament_L170.mp4", "pendulum", RED,
         stated={"L": (1.7, "about 1.7 m"), "amplitude": (15.0, "15 deg")},
         fitode_args=["--system", "pendulum"], fitode_param="L"),
    Clip("freefall_balldrop_slowmo120.mp4", "freefall", RED_BALL, fps=120.0,
         stated={"g": (9.81, "9.81 (author's own fit 8.78)")},
         # the README's command: release at the ceiling (frame 118), the floor at frame 199, 232 cm apart
         fitode_args=["--eq", "d'' = g", "--free", "g", "--fps", "120", "--start", "0.98", "--end", "1.66",
                      "--calibrate", "d(0.984)=0.02; d(1.658)=2.30"], fitode_param="g"),
    Clip("draining_bottle_hole7mm.mp4", "bottle", RED_WATER,
         stated={"k": (None, "none (7 mm hole, 16.5 cm tall)")},
         fitode_args=["--system", "torricelli", "--start", "3", "--observe", "position"], fitode_param="k"),
    Clip("bouncing_ball.avi", "bounce", GREEN,
         stated={"g": (9.81, "9.81 (G in the script)")},
         # as a user would: every flight, no --start/--end, the scale from the ball's diameter (85 px = 6.87 cm)
         fitode_args=["--eq", "y'' = -g", "--free", "g", "--scale", "0,0,85,0=0.0687"], fitode_param="g"),
]}


# ----------------------------------------------------------------------------- video and tracking
def read_frames(path: str | Path) -> Iterator[np.ndarray]:
    """Every decodable BGR frame of a video file (OpenCV)."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                return
            yield frame
    finally:
        cap.release()


def frame_rate(path: str | Path) -> float:
    """The clip's real frame rate: from the frames' own timestamps where they run steadily (the
    apple clip's header says 59.768 fps while every frame is stamped 1/59.94 s after the last),
    else the header's rate (an AVI's stamps can run backwards)."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    cap.release()
    try:
        import av

        with av.open(str(path)) as box:
            stream = box.streams.video[0]
            stamps = np.array([f.time for f in box.decode(stream) if f.time is not None], dtype=float)
    except Exception:  # no PyAV or an unreadable container: the header's rate
        return fps
    steps = np.diff(stamps)
    if len(steps) < 10 or steps.min() <= 0 or steps.max() > 1.5 * steps.min():
        return fps
    return float(1.0 / np.polyfit(np.arange(len(stamps)), stamps, 1)[0])


def colour_mask(frame_bgr: np.ndarray, ranges) -> np.ndarray:
    """uint8 0/1 mask of the pixels inside any of the HSV ranges."""
    import cv2

    hsv = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2HSV)
    m = np.zeros(hsv.shape[:2], np.uint8)
    for lo, hi in ranges:
        m |= cv2.inRange(hsv, np.array(lo, np.uint8), np.array(hi, np.uint8))
    return (m > 0).astype(np.uint8)


def largest_blob(mask: np.ndarray, min_area: int = 20) -> tuple[float, float, int, int, int] | None:
    """(cx, cy, area, width, height) of the mask's largest connected blob, None if under min_area."""
    import cv2

    n, _, stats, cent = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    area = int(stats[k, cv2.CC_STAT_AREA])
    if area < min_area:
        return None
    return (float(cent[k, 0]), float(cent[k, 1]), area,
            int(stats[k, cv2.CC_STAT_WIDTH]), int(stats[k, cv2.CC_STAT_HEIGHT]))


def track_colour(frames, ranges, min_area: int = 20) -> dict[str, np.ndarray]:
    """Per frame: centroid x, y, area, width, height of the largest blob of that colour (NaN if none)."""
    rows = []
    for f in frames:
        b = largest_blob(colour_mask(f, ranges), min_area)
        rows.append(b if b is not None else (math.nan,) * 5)
    a = np.asarray(rows, dtype=float).reshape(-1, 5)
    return {"x": a[:, 0], "y": a[:, 1], "area": a[:, 2], "w": a[:, 3], "h": a[:, 4]}


# ----------------------------------------------------------------------------- fits
def _cov(res) -> np.ndarray:
    """Parameter covariance of a scipy least_squares result: (J^T J)^-1 * residual variance."""
    J = res.jac
    dof = max(1, J.shape[0] - J.shape[1])
    s2 = 2 * res.cost / dof
    return np.linalg.pinv(J.T @ J) * s2


def main_axis(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(s, q): coordinates along the track's first principal axis and across it (pixels, centred)."""
    P = np.stack([x - x.mean(), y - y.mean()], 1)
    _, _, vt = np.linalg.svd(P, full_matrices=False)
    u = vt[0] if abs(vt[0, 0]) >= abs(vt[0, 1]) or vt[0, 0] != 0 else vt[0]
    if u[0] < 0:  # +s to the right
        u = -u
    v = np.array([-u[1], u[0]])
    if v[1] < 0:  # +q downwards in the image
        v = -v
    return P @ u, P @ v


def fft_frequency(t: np.ndarray, x: np.ndarray) -> float:
    """Angular frequency of the largest peak of the zero-padded spectrum (uniform t)."""
    dt = float(np.median(np.diff(t)))
    n = 1 << int(math.ceil(math.log2(len(x) * 8)))
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(len(x)), n))
    freqs = np.fft.rfftfreq(n, dt)
    spec[freqs < 2.0 / (t[-1] - t[0])] = 0  # at least two cycles in the record
    return 2 * math.pi * float(freqs[int(np.argmax(spec))])


def fit_damped_sinusoid(t: np.ndarray, x: np.ndarray) -> dict[str, Any]:
    """x = A exp(-r t) cos(w t + phi) + c (r = 1/tau); w_0 = sqrt(w^2 + r^2), T = 2 pi / w_0."""
    from scipy.optimize import least_squares

    t = np.asarray(t, float)
    x = np.asarray(x, float)
    t0 = t[0]
    tt = t - t0
    w = fft_frequency(tt, x)
    M = np.stack([np.cos(w * tt), np.sin(w * tt), np.ones_like(tt)], 1)
    (a, b, c), *_ = np.linalg.lstsq(M, x, rcond=None)
    p0 = [math.hypot(a, b), 0.0, w, math.atan2(-b, a), c]

    def model(p, tt):
        A, r, w, phi, c = p
        return A * np.exp(-r * tt) * np.cos(w * tt + phi) + c

    res = least_squares(lambda p: model(p, tt) - x, p0, x_scale="jac")
    A, r, w, phi, c = res.x
    if A < 0:
        A, phi = -A, phi + math.pi
    cov = _cov(res)
    w0 = math.sqrt(w * w + r * r)
    grad = np.array([0.0, r / w0, w / w0, 0.0, 0.0])
    se_w0 = math.sqrt(max(0.0, float(grad @ cov @ grad)))
    T = 2 * math.pi / w0
    rms = math.sqrt(2 * res.cost / len(x))
    return {"A": float(A), "rate": float(r), "tau": (1.0 / r) if r > 0 else math.inf,
            "se_rate": math.sqrt(max(0.0, cov[1, 1])), "w": float(w), "se_w": math.sqrt(max(0.0, cov[2, 2])),
            "phi": float(phi), "c": float(c), "w0": w0, "T": T, "se_T": T * se_w0 / w0,
            "zeta": 2 * float(r), "rms_px": rms, "n": int(len(x)), "t_start": float(t0),
            "residuals": (model(res.x, tt) - x)}


def polyfit_se(t: np.ndarray, y: np.ndarray, deg: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares polynomial (lowest power first), its standard errors and the rms residual."""
    V = np.vander(t, deg + 1, increasing=True)
    coef, *_ = np.linalg.lstsq(V, y, rcond=None)
    r = y - V @ coef
    dof = max(1, len(y) - deg - 1)
    cov = np.linalg.pinv(V.T @ V) * float(r @ r) / dof
    return coef, np.sqrt(np.maximum(np.diag(cov), 0)), math.sqrt(float(r @ r) / len(y))


def pendulum_truth(t: np.ndarray, x: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    """Period, amplitude and equivalent length of a tracked bob (see the module docstring)."""
    ok = np.isfinite(x) & np.isfinite(y)
    t, x, y = t[ok], x[ok], y[ok]
    s, q = main_axis(x, y)
    fit = fit_damped_sinusoid(t, s)
    half = len(t) // 2
    halves = [fit_damped_sinusoid(t[:half], s[:half])["T"], fit_damped_sinusoid(t[half:], s[half:])["T"]]
    # arc curvature: q = q0 + q1 s + q2 s^2, bob rises (q decreases) at the ends -> q2 < 0
    coef, se, _ = polyfit_se(s, q, 2)
    L_px = se_L_px = math.nan
    theta_max = math.nan
    mean_theta2 = 0.0
    amp_note = "not measurable (arc curvature under 3 standard errors); no amplitude correction"
    if coef[2] < 0 and abs(coef[2]) > 3 * se[2]:
        L_px = -1.0 / (2 * coef[2])
        se_L_px = L_px * se[2] / abs(coef[2])
        amp_px = fit["A"] * np.exp(-fit["rate"] * (t - t[0]))
        theta = np.arcsin(np.clip(amp_px / L_px, 0, 1))
        theta_max = float(theta[0])
        mean_theta2 = float(np.mean(theta ** 2))
        amp_note = "from the arc's curvature (L_px) and the fitted amplitude"
    T = fit["T"]
    T0 = T / (1 + mean_theta2 / 16)
    se_T0 = fit["se_T"] / (1 + mean_theta2 / 16)
    L = G * T0 ** 2 / (4 * math.pi ** 2)
    se_L = L * 2 * se_T0 / T0
    out = {k: v for k, v in fit.items() if k != "residuals"}
    out.update({"T_undamped": T, "se_T_undamped": fit["se_T"], "T_halves": halves,
                "T0": T0, "se_T0": se_T0, "L": L, "se_L": se_L, "L_px": L_px, "se_L_px": se_L_px,
                "amplitude_deg": math.degrees(theta_max) if math.isfinite(theta_max) else None,
                "rms_amplitude_deg": math.degrees(math.sqrt(mean_theta2)) if mean_theta2 else None,
                "amplitude_note": amp_note, "frames_tracked": int(ok.sum())})
    return out


def parabola_fit(t: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    """y = y0 + v0 t + g t^2 / 2 (pixels): g = 2 * c2 and its standard error."""
    coef, se, rms = polyfit_se(t - t[0], y, 2)
    return {"y0": float(coef[0]), "v0": float(coef[1]), "g_px": 2 * float(coef[2]), "se_g_px": 2 * float(se[2]),
            "rms_px": rms, "n": int(len(t)), "t_start": float(t[0]), "t_end": float(t[-1])}


# ----------------------------------------------------------------------------- per kind
def step_row(profile: np.ndarray, lo: int, hi: int) -> int:
    """The row in [lo, hi) where a (smoothed) brightness profile changes most."""
    p = np.convolve(profile, np.ones(3) / 3, mode="same")
    d = np.abs(np.diff(p[lo:hi]))
    return lo + int(np.argmax(d)) + 1


def first_step(profile: np.ndarray, lo: int, hi: int, thresh: float) -> int:
    """The first row in [lo, hi) whose brightness differs from the band's start (the median of its
    first 20 rows) by more than thresh: the edge of the first object below a plain background."""
    ref = float(np.median(profile[lo:lo + 20]))
    d = np.where(np.abs(profile[lo:hi] - ref) > thresh)[0]
    return lo + int(d[0]) if d.size else lo


def measure_pendulum(path: Path, clip: Clip, frames: list[np.ndarray] | None = None) -> dict[str, Any]:
    fps = clip.fps or frame_rate(path)
    tr = track_colour(frames if frames is not None else read_frames(path), clip.hsv)
    n = len(tr["x"])
    t = np.arange(n) / fps
    res = pendulum_truth(t, tr["x"], tr["y"])
    res.update({"fps": fps, "frames": n})
    rows = [{"quantity": "T (undamped, s)", "value": res["T0"], "err": res["se_T0"]},
            {"quantity": "amplitude (deg)", "value": res["amplitude_deg"], "err": None},
            {"quantity": "L (m)", "value": res["L"], "err": res["se_L"]},
            {"quantity": "zeta (1/s)", "value": res["zeta"], "err": 2 * res["se_rate"]}]
    return {"fit": res, "rows": rows, "track": tr, "draw_frame": int(np.nanargmax(np.abs(tr["x"] - np.nanmedian(tr["x"]))))}


def measure_freefall(path: Path, clip: Clip) -> dict[str, Any]:
    frames = list(read_frames(path))
    tr = track_colour(frames, clip.hsv)
    y, area = tr["y"], tr["area"]
    # the hand lifts the ball a little and lets go at its highest point (smallest row) before it falls
    start = 100 + int(np.nanargmin(y[100:130]))
    end = start
    while end + 1 < len(y) and np.isfinite(y[end + 1]) and area[end + 1] >= 100 and y[end + 1] > y[end]:
        end += 1
    idx = np.arange(start, end + 1)
    t = idx / clip.fps
    fit = parabola_fit(t, y[idx])
    import cv2

    g = cv2.cvtColor(frames[start], cv2.COLOR_BGR2GRAY).astype(float)
    profile = g[:, g.shape[1] // 2:].mean(1)  # right half: away from the hand and ball
    H = g.shape[0]
    ceiling = first_step(profile, 20, 300, 15.0)
    floor = step_row(profile, H - 250, H - 10)
    m_per_px = 2.32 / (floor - ceiling)
    width = float(np.median(tr["w"][idx]))
    m_per_px_ball = 0.04 / width
    g_m = fit["g_px"] * m_per_px
    fit.update({"start_frame": start, "end_frame": end, "ceiling_row": ceiling,
                "floor_row": floor, "m_per_px": m_per_px, "g": g_m, "se_g": fit["se_g_px"] * m_per_px,
                "ball_width_px": width, "g_ball_scale": fit["g_px"] * m_per_px_ball,
                "scale_note": "232 cm between the ceiling row (cornice top) and the floor row (carpet edge)"})
    # the early frames (ball leaving the fingers) pull g up: the same fit from 8 frames later
    late = np.arange(start + 8, end + 1)
    g_late = parabola_fit(late / clip.fps, y[late])["g_px"] * m_per_px
    fit["g_from_release_plus_8"] = g_late
    rows = [{"quantity": "g (m/s^2)", "value": g_m, "err": fit["se_g"]},
            {"quantity": "g, from release+8 frames", "value": g_late, "err": None},
            {"quantity": "g, ball-diameter scale", "value": fit["g_ball_scale"],
             "err": fit["se_g_px"] * m_per_px_ball}]
    return {"fit": fit, "rows": rows, "track": tr, "frames": frames, "draw_frame": (start + end) // 2,
            "lines": [ceiling, floor]}


def measure_bottle(path: Path, clip: Clip, x0: int = 360, x1: int = 530, t_start: float = 3.0,
                   min_rows: int = 12) -> dict[str, Any]:
    import cv2

    fps = clip.fps or frame_rate(path)
    levels, bottoms, first = [], [], None
    for i, f in enumerate(read_frames(path)):
        if first is None and i / fps >= t_start:
            first = f
        m = colour_mask(f, clip.hsv)[:, x0:x1]
        water = np.where(m.mean(1) > 0.5)[0]
        if water.size == 0:
            levels.append(math.nan)
            bottoms.append(math.nan)
            continue
        # the longest run of water rows (gaps up to 2 rows bridged): the column, not the jet below
        runs = np.split(water, np.where(np.diff(water) > 3)[0] + 1)
        run = max(runs, key=len)
        top, bot = int(run[0]), int(run[-1])
        levels.append(float(top))
        bottoms.append(float(bot))
    levels, bottoms = np.asarray(levels), np.asarray(bottoms)
    t = np.arange(len(levels)) / fps
    use = (t >= t_start) & np.isfinite(levels)
    bottom = float(np.nanpercentile(bottoms[use], 95))
    h = bottom - levels
    use &= h >= min_rows
    # stop at the first frame the column is too short: later detections are the meniscus
    last = np.where(use)[0]
    idx = last[: int(np.argmax(np.diff(last) > 1)) + 1] if (np.diff(last) > 1).any() else last
    g = cv2.cvtColor(first, cv2.COLOR_BGR2GRAY).astype(float)
    profile = g[:, x0 + 40:x1 - 30].mean(1)
    rim = first_step(profile, 150, int(np.nanmin(levels[idx])), 5.0)
    cm_per_px = 16.5 / (bottom - rim)
    sq = np.sqrt(h[idx])
    coef, se, rms = polyfit_se(t[idx], sq, 1)
    k_px, se_px = -2 * float(coef[1]), 2 * float(se[1])
    k_cm, se_cm = k_px * math.sqrt(cm_per_px), se_px * math.sqrt(cm_per_px)
    fit = {"k_px": k_px, "se_k_px": se_px, "k_cm": k_cm, "se_k_cm": se_cm, "k_m": k_cm / 10, "se_k_m": se_cm / 10,
           "h0_px": float(coef[0]) ** 2, "rms_sqrt_px": rms, "bottom_row": bottom, "rim_row": rim,
           "cm_per_px": cm_per_px, "t_start": float(t[idx[0]]), "t_end": float(t[idx[-1]]), "n": int(len(idx)),
           "fps": fps, "h_px_start": float(h[idx[0]]), "h_px_end": float(h[idx[-1]])}
    rows = [{"quantity": "k (px^0.5/s)", "value": k_px, "err": se_px},
            {"quantity": "k (cm^0.5/s)", "value": k_cm, "err": se_cm},
            {"quantity": "k (m^0.5/s)", "value": fit["k_m"], "err": fit["se_k_m"]}]
    return {"fit": fit, "rows": rows, "levels": levels, "draw_frame": int(idx[0]) + (int(idx[-1]) - int(idx[0])) // 3,
            "lines": [rim, int(bottom)]}


def measure_bounce(path: Path, clip: Clip, first: int = 63, last: int = 117) -> dict[str, Any]:
    fps = clip.fps or frame_rate(path)
    frames = list(read_frames(path))
    tr = track_colour(frames, clip.hsv, min_area=200)
    y = tr["y"]
    idx = np.arange(first, min(last, len(y) - 1) + 1)
    idx = idx[np.isfinite(y[idx])]
    yy = y[idx]
    rest = float(np.median(yy[:3]))
    start_k = int(np.argmax(yy > rest + 2.0)) - 1  # release
    # first bounce: the first local maximum of y (lowest point) after the release
    k = start_k + 1
    while k + 1 < len(yy) and yy[k + 1] >= yy[k]:
        k += 1
    sel = idx[max(start_k, 0):k]  # the flight, without the frame at the floor
    fit = parabola_fit(sel / fps, y[sel])
    m_per_px = 0.0687 / 85
    fit.update({"g": fit["g_px"] * m_per_px, "se_g": fit["se_g_px"] * m_per_px, "m_per_px": m_per_px,
                "start_frame": int(sel[0]), "end_frame": int(sel[-1]), "fps": fps})
    rows = [{"quantity": "g (m/s^2)", "value": fit["g"], "err": fit["se_g"]}]
    return {"fit": fit, "rows": rows, "track": tr, "frames": frames, "draw_frame": int(sel[len(sel) // 2])}


# ----------------------------------------------------------------------------- fitode
def fitode_calibration(clip: Clip, m: dict[str, Any]) -> list[str]:
    """--start/--end/--calibrate for the scale-dependent fits, from the tracker's own fit (two
    positions a user would read off a ruler)."""
    f = m["fit"]
    if "--calibrate" in clip.fitode_args or "--scale" in clip.fitode_args:  # the command carries its own units
        return []
    if clip.kind in ("freefall", "bounce"):
        fps = clip.fps or f.get("fps")
        t0, t1 = f["start_frame"] / fps, f["end_frame"] / fps
        mpp = f["m_per_px"]

        def y(t):  # metres fallen from the first frame, by the tracker's parabola
            tt = t - f["t_start"]
            return (f["v0"] * tt + f["g_px"] * tt * tt / 2) * mpp

        # --end half a frame late: t1 written to 4 decimals may fall just before its own frame
        return ["--start", f"{t0:.4f}", "--end", f"{t1 + 0.5 / fps:.4f}",
                "--calibrate", f"y({t0:.4f})={y(t0):.4f}; y({t1:.4f})={y(t1):.4f}"]
    if clip.kind == "bottle":
        t0, t1 = f["t_start"], f["t_end"]

        def h(t):  # metres, by the tracker's Torricelli fit
            r = math.sqrt(f["h0_px"]) - f["k_px"] * t / 2
            return max(r, 0.0) ** 2 * f["cm_per_px"] / 100

        return ["--end", f"{t1:.3f}", "--calibrate", f"h({t0:.3f})={h(t0):.5f}; h({t1:.3f})={h(t1):.5f}"]
    return []


def run_fitode(path: Path, clip: Clip, m: dict[str, Any], out_dir: Path, timeout: float) -> dict[str, Any]:
    """The documented command line, `fitode CLIP --system ... --quiet --json --out DIR`, in a subprocess."""
    run_dir = out_dir / f"fitode-{Path(clip.name).stem}"
    if run_dir.exists() and any(run_dir.iterdir()):
        import shutil
        shutil.rmtree(run_dir)
    cmd = [sys.executable, "-m", "fitode", str(path), *clip.fitode_args, *fitode_calibration(clip, m),
           "--quiet", "--json", "--out", str(run_dir)]
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=REPO)
    except subprocess.TimeoutExpired:
        return {"command": cmd, "error": f"timed out after {timeout:.0f} s"}
    wall = time.perf_counter() - t0
    rec: dict[str, Any] = {"command": cmd, "returncode": p.returncode, "wall_s": wall}
    try:
        result = json.loads(p.stdout)
    except ValueError:
        rec["error"] = (p.stderr.strip().splitlines() or ["no output"])[-1]
        return rec
    if clip.kind == "bottle":
        rec["travel"] = reading_travel(run_dir / "track.csv", m["levels"])
    par = (result.get("parameters") or {}).get(clip.fitode_param) or {}
    rec.update({"value": par.get("value"), "std": par.get("std"), "interval": par.get("interval"), "unit": par.get("unit"),
                "calibrated": par.get("calibrated"), "status": result.get("status"), "verdict": par.get("verdict"),
                "warnings": result.get("warnings", [])})
    return rec


def reading_travel(track_csv: Path, levels: np.ndarray) -> dict[str, Any] | None:
    """How far fitode's reading (track.csv's y_px, source pixels) moves against the colour
    tracker's water top (levels, per source frame) on the frames both read: each one's travel
    (largest minus smallest row), their ratio, and the slope of fitode's rows on the tracker's."""
    import csv

    if not track_csv.exists():
        return None
    with open(track_csv) as f:
        rows = [(int(r["frame"]), float(r["y_px"])) for r in csv.DictReader(f) if r.get("y_px")]
    if not rows:
        return None
    frames, y = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    inside = frames < len(levels)
    frames, y = frames[inside], y[inside]
    top = levels[frames]
    both = np.isfinite(top) & np.isfinite(y)
    if both.sum() < 3:
        return None
    fitode_px, tracker_px = float(np.ptp(y[both])), float(np.ptp(top[both]))
    return {"frames": int(both.sum()), "fitode_px": fitode_px, "tracker_px": tracker_px,
            "ratio": fitode_px / tracker_px if tracker_px else math.nan,
            "slope": float(np.polyfit(top[both], y[both], 1)[0])}


# ----------------------------------------------------------------------------- check images
def save_check_image(path: Path, clip: Clip, m: dict[str, Any], folder: Path) -> Path:
    """One frame with the detection drawn (centroid circle, the level line, the scale rows)."""
    import cv2

    k = int(m["draw_frame"])
    frames = m.get("frames")
    frame = frames[k] if frames is not None else next(f for i, f in enumerate(read_frames(path)) if i == k)
    img = frame.copy()
    mask = colour_mask(img, clip.hsv).astype(bool)
    img[mask] = (0.5 * img[mask] + 0.5 * np.array([255, 255, 0])).astype(np.uint8)  # cyan tint: thresholded
    tr = m.get("track")
    if tr is not None and np.isfinite(tr["x"][k]):
        c = (int(round(tr["x"][k])), int(round(tr["y"][k])))
        cv2.circle(img, c, 6, (0, 255, 0), 2)
        cv2.drawMarker(img, c, (0, 0, 0), cv2.MARKER_CROSS, 10, 1)
    if "levels" in m and np.isfinite(m["levels"][k]):
        yk = int(m["levels"][k])
        cv2.line(img, (300, yk), (600, yk), (0, 255, 0), 2)
    for row in m.get("lines", []):
        cv2.line(img, (0, int(row)), (img.shape[1], int(row)), (255, 0, 255), 1)
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / f"{Path(clip.name).stem}_f{k}.png"
    cv2.imwrite(str(out), img)
    return out


# ----------------------------------------------------------------------------- driver
MEASURE: dict[str, Callable[[Path, Clip], dict[str, Any]]] = {
    "pendulum": measure_pendulum, "freefall": measure_freefall, "bottle": measure_bottle, "bounce": measure_bounce,
}


def find_clips(folder: Path, names: Sequence[str]) -> tuple[list[tuple[str, Path]], list[str]]:
    """(name, path) of the clips present, and one skip message per missing folder or clip."""
    if not folder.is_dir():
        return [], [f"skip: no clip folder {folder} (the real clips live in ../shared/realvideos)"]
    found, skips = [], []
    for n in names:
        p = folder / n
        if p.is_file():
            found.append((n, p))
        else:
            skips.append(f"skip: {n}: not in {folder}")
    return found, skips


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--clips", default=",".join(CLIPS), metavar="NAME,...",
                        help="which clips (default all: " + ", ".join(CLIPS) + ")")
    parser.add_argument("--dir", default=str(CLIP_DIR), metavar="DIR",
                        help=f"folder of the clips (default {CLIP_DIR})")
    parser.add_argument("--fitode", action="store_true",
                        help="also run the documented fitode command on every clip (minutes each)")
    parser.add_argument("--fitode-timeout", type=float, default=1800, metavar="S",
                        help="seconds per fitode run (default 1800)")
    parser.add_argument("--check-images", default=None, metavar="DIR",
                        help="save one frame per clip with the detection drawn")
    parser.add_argument("--out", default=str(bc.DEFAULT_OUT), metavar="DIR",
                        help=f"folder for the JSON record (default {bc.DEFAULT_OUT})")


def _fmt(v: Any, e: Any) -> str:
    """value +- error, the error to 2 significant digits and the value to the same decimal place."""
    if v is None or not math.isfinite(float(v)):
        return "-"
    if e is None or not math.isfinite(float(e)) or e <= 0:
        return f"{v:.4g}"
    dec = max(0, 1 - int(math.floor(math.log10(e))))
    return f"{v:.{dec}f} +- {e:.{dec}f}"


def _row_key(q: str) -> str:
    return "L" if q.startswith("L") else "g" if q.startswith("g (") else "k" if q.startswith("k (m") else \
        "amplitude" if q.startswith("amplitude") else ""


def run(args: argparse.Namespace) -> int:
    names = bc.pick(args.clips, list(CLIPS), "--clips")
    t_all = time.perf_counter()
    found, skips = find_clips(Path(args.dir), names)
    for s in skips:
        bc.progress(s)
    out = Path(args.out)
    results: dict[str, Any] = {}
    table = []
    for name, path in found:
        clip = CLIPS[name]
        bc.progress(f"{name}: tracking ...")
        t0 = time.perf_counter()
        try:
            m = MEASURE[clip.kind](path, clip)
        except Exception as exc:  # a clip the tracker cannot follow is reported, not fatal
            bc.progress(f"skip: {name}: tracker failed ({type(exc).__name__}: {exc})")
            results[name] = {"error": f"{type(exc).__name__}: {exc}"}
            continue
        rec: dict[str, Any] = {"kind": clip.kind, "tracker": m["fit"], "rows": m["rows"],
                               "stated": {k: {"value": v, "text": t} for k, (v, t) in clip.stated.items()},
                               "track_s": time.perf_counter() - t0}
        if args.check_images:
            rec["check_image"] = str(save_check_image(path, clip, m, Path(args.check_images)))
        if args.fitode:
            bc.progress(f"{name}: fitode {' '.join(clip.fitode_args)} ...")
            rec["fitode"] = run_fitode(path, clip, m, out / "realclips", args.fitode_timeout)
        results[name] = rec
        for r in m["rows"]:
            key = _row_key(r["quantity"])
            stated = clip.stated.get(key, (None, ""))[1] if key else ""
            fit_txt = ""
            if key == clip.fitode_param or (key == "L" and clip.fitode_param == "L"):
                f = rec.get("fitode")
                iv = (f or {}).get("interval")
                within = "" if not iv else f", 95% [{iv[0]:.5g}, {iv[1]:.5g}]" + (
                    " holds the tracker's" if iv[0] <= r["value"] <= iv[1] else " misses the tracker's")
                # the value to the interval's digits: the restarts' spread beside it (3e-10 on the bottle,
                # where every restart lands alike) says nothing of how well the clip pins it
                value = f"{f['value']:.5g}" if f and iv and f.get("value") is not None else \
                    _fmt((f or {}).get("value"), (f or {}).get("std"))
                fit_txt = ("not run" if f is None else f.get("error")
                           or f"{value}{within} ({f.get('verdict') or 'no verdict'})")
            table.append({"clip": name, "quantity": r["quantity"], "tracker": _fmt(r["value"], r["err"]),
                          "stated": stated, "fitode": fit_txt})
        bc.progress(f"{name}: done in {time.perf_counter() - t0:.0f} s")
    wall = time.perf_counter() - t_all
    record = {"benchmark": "realclips", "clip_dir": str(Path(args.dir)), "skips": skips, "clips": results,
              "table": table, "wall_s": wall, "machine": bc.machine_info()}
    path = bc.write_record(record, out, "realclips")
    print(bc.format_table(table, [("clip", "clip"), ("quantity", "quantity"), ("tracker", "tracker"),
                                  ("SOURCES.md", "stated"), ("fitode", "fitode")],
                          title="real clips: colour tracker + curve fit (errors: fit standard errors)"))
    for name, rec in results.items():
        travel = (rec.get("fitode") or {}).get("travel")
        if travel:
            print(f"{name}: fitode's reading travels {travel['fitode_px']:.1f} source pixels, the colour tracker's "
                  f"water top {travel['tracker_px']:.1f}, on the {travel['frames']} frames both read: ratio "
                  f"{travel['ratio']:.3f} (slope of fitode's rows on the tracker's {travel['slope']:.3f})")
    for s in skips:
        print(s)
    print(f"wrote {path}; {bc.ran_on(record)}")
    return 0


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
