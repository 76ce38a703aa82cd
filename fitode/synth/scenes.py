"""Realistic scenes modelled on the paper's real dataset (Delfys75): a camera on a tripod
filming five experiments at 60 fps.

Each frame is drawn in linear RGB (textured seeded background, lit and shaded objects, soft
shadows, anti-aliased at 4x supersampling), then passed through a camera model: lens
vignetting, mild optical blur, signal-dependent sensor noise, the sRGB transfer curve that
video stores (fitode.video.light), 8-bit quantisation and a JPEG
round trip (a lossy codec on every frame). Frames are uint8 RGB (T, H, W, 3).

The dynamics are the physics, not a fit target's approximation:
- pendulum: theta'' = -g/L sin(theta) - zeta theta' (nonlinear), integrated with the
  project's RK4 at 20 sub-steps per frame; L = 0.45, 0.9, 1.5 m; zeta = 0.05 /s.
- torricelli: h' = -k sqrt(h) in metres and seconds, exact: sqrt(h) = sqrt(h0) - k t / 2;
  a floating ball marks the level; k = 0.0095, 0.0128, 0.0162 m^0.5/s.
- sliding_block: s'' = g (sin(alpha) - mu cos(alpha)) = a (s along the incline), exact; alpha = 20, 25, 30 deg,
  mu = 0.21; the block starts near the top, already released t0 seconds before frame 0.
  The truth is alpha (radians) and mu, the shipped file's constants; only their combination
  a (meta["physical"]["a"]) is measurable.
- led: I' = -gamma (I - c) with the dark level c = 0, exact; nothing saturates, so the light is
  affine in the LED's brightness, and the pixel values are its sRGB encoding (a latent linear in
  them measures about I**(1/2.2)); gamma = 2.3, 0.92, 0.46 /s.
- free_fall: a ball dropped h0 = 0.20 m below a camera looking straight down; its distance
  d = h0 + g t^2 / 2 (d'' = g) and its apparent radius r0 f / d (the dataset's model,
  f = 1451 px/m at 1920 px wide, scaled with the width here); r0 = 0.0335, 0.06, 0.10 m.
- spring: y'' = -w2 y - c y' (exact), a can's height on a spring; it also sways sideways (another
  frequency) and turns, and a ball is carried across the view behind it (distractors = 1 or 2
  crossings; legs = 2: two dark legs walk back and forth behind it); w2 = 12, 18, 30 1/s^2, c = 0.08 /s.
- throw: y'' = -g (exact), a small ball (1.4 pixels in radius at 320x240) thrown across the view,
  held still before and lying still after (rest_before, rest_after seconds); meta["physical"] has
  the flight's frames and the horizontal x. Film it with fps=240 and store it at 30 (a phone's
  slow motion): dataclasses.replace(video, dt=1/30) before write_video.
- held_pendulum, bumper_cart, bouncing_ball: clips as they are filmed (a hand that holds and lets
  go; a cart bouncing off its bumper; a ball bouncing), each with a ruler in view.
- sliding_puck: x'' = -a (exact) while it slides: a puck on a table, at rest, pushed by a hand
  (its speed rising as 1 - cos over push_s seconds), sliding until friction stops it, at rest;
  a = 0.5, 1.5, 3 m/s^2; a ruler in view.
Each equation is, word for word, that of a shipped equation file, named in meta["system"]
(pendulum, torricelli, sliding_block, led_decay, free_fall_scale). The ground truth (its
constants, the latent trajectory) is in SynthVideo.truth and .latent; physical extras (g, a,
alpha in degrees, r0, f, ...) in meta["physical"].
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from fitode.errors import FitodeError
from fitode.synth import render as R
from fitode.synth.video import SynthVideo
from fitode.video.light import linear_to_srgb

G = 9.80665


@dataclass
class _Scene:
    """What a scene builder hands the common camera loop."""

    background: np.ndarray                 # (H, W, 3) float32 linear RGB
    draw: Callable[[R.Canvas, int], None]  # paints frame i's moving parts
    latent: np.ndarray                     # (T, dim)
    latent_names: tuple[str, ...]
    truth: dict[str, float]
    physical: dict[str, float]
    state: np.ndarray | None = None
    state_names: tuple[str, ...] = ()
    overlay: Callable[[R.Canvas, int], None] | None = None  # painted after draw (glass, ...)
    pixels: np.ndarray | None = None  # (T, 2) the object's true centre (x, y) in pixel units, where the scene knows it


def scene(name: str, setting: float | None = None, *, seed: int = 0, duration: float | None = None,
          fps: float = 60.0, size: tuple[int, int] = (270, 480), noise: float = 1.0,
          blur: float = 0.7, jpeg_quality: int = 85, ss: int = 4, curve: str = "srgb", **params: float) -> SynthVideo:
    """Render one realistic scene.

    setting: the dataset's varied quantity (L, k, alpha in degrees, gamma, r0 in metres; see
        SCENES), positionally or by its name (scene("pendulum", L=0.9)); None: the middle
        value. Any value in a physically sensible range is accepted.
    seed: initial conditions (pendulum angle, tank level, ...), textures and sensor noise.
    duration: seconds (None: the scene's default, for sliding_block and free_fall as long as
        the motion lasts, which is also the maximum).
    size: (height, width) in pixels.
    noise: sensor-noise multiplier (1: a decent camera, 0: none). blur: optical blur sigma
        in pixels. jpeg_quality: 1..100 (100: no compression). curve: the transfer curve the
        camera stores, "srgb" (a phone, a webcam) or "linear" (a scientific camera, a rendering).
    params: scene-specific overrides (pendulum: zeta, theta0_deg; torricelli: h0;
        sliding_block: mu, t0, rest_before, rest_after (seconds still before and after); led: I0; free_fall: h0, floor).
    """
    if name not in SCENES:
        raise FitodeError(f"unknown scene '{name}': choose one of {', '.join(SCENES)}")
    info = SCENES[name]
    if info.setting in params:  # scene("pendulum", L=0.9) reads as well as scene("pendulum", 0.9)
        if setting is not None:
            raise FitodeError(f"give the {info.setting} of scene '{name}' once")
        setting = params.pop(info.setting)
    if setting is None:
        setting = info.settings[len(info.settings) // 2]
    setting = float(setting)
    h, w = (int(size[0]), int(size[1]))
    if not (32 <= h <= 4320 and 32 <= w <= 7680):
        raise FitodeError(f"scene size must be between 32 and 7680 pixels a side, got {w}x{h}")
    if not (fps > 0 and np.isfinite(fps)):
        raise FitodeError(f"fps must be positive, got {fps}")
    if duration is not None and not (duration > 0 and np.isfinite(duration)):
        raise FitodeError(f"duration must be a positive number of seconds, got {duration}")
    if not 1 <= int(jpeg_quality) <= 100:
        raise FitodeError(f"jpeg_quality must be between 1 and 100, got {jpeg_quality}")
    if noise < 0 or blur < 0:
        raise FitodeError("noise and blur must not be negative")
    if curve not in ("srgb", "linear"):
        raise FitodeError(f"unknown transfer curve '{curve}': choose srgb or linear")
    unknown = set(params) - set(info.params)
    if unknown:
        raise FitodeError(f"scene '{name}' has no parameter {', '.join(sorted(unknown))} "
                          f"(it takes {', '.join(info.params) or 'none'})")
    if duration is None:
        duration = info.default_duration
    rng = np.random.default_rng([int(seed), 17])
    dt = 1.0 / float(fps)
    sc = info.build(setting, rng, duration, dt, h, w, params)
    n = sc.latent.shape[0]
    frames = np.empty((n, h, w, 3), np.uint8)
    vig = R.vignette(h, w, 0.22)[..., None]
    sensor = _Sensor(np.random.default_rng([int(seed), 29]), (h, w, 3), noise, blur, int(jpeg_quality), curve)
    for i in range(n):
        cv = R.Canvas(sc.background.copy(), ss)
        sc.draw(cv, i)
        if sc.overlay is not None:
            sc.overlay(cv, i)
        cv.image *= vig
        frames[i] = sensor(cv.image)
    meta = {
        "generator": "scene", "name": name, "setting_name": info.setting, "setting": setting,
        "setting_unit": info.unit, "system": info.system, "seed": int(seed), "fps": float(fps), "size": [h, w],
        "duration": n * dt, "noise": noise, "blur": blur, "jpeg_quality": int(jpeg_quality),
        "params": {k: float(v) for k, v in params.items()}, "physical": sc.physical, "curve": curve,
        "description": info.description,
    }
    return SynthVideo(frames=frames, dt=dt, truth=sc.truth, latent=sc.latent, equation=info.equation,
                      latent_names=sc.latent_names, state=sc.state, state_names=sc.state_names,
                      meta=meta, pixels=sc.pixels)


class _Sensor:
    """Linear RGB in [0, 1] -> what a camera records: blur, shot + read noise, the sRGB transfer
    curve, 8 bits, JPEG.

    Gaussian draws dominate the cost of a frame, so every frame reads its noise from one
    seeded bank of three frames' worth at a random offset: each frame's noise is i.i.d.
    normal, and what two frames share is shifted by a random number of pixels."""

    def __init__(self, rng: np.random.Generator, shape: tuple[int, ...], noise: float, blur: float,
                 quality: int, curve: str = "srgb"):
        self.rng, self.shape, self.noise, self.blur, self.quality = rng, shape, noise, blur, quality
        self.encode = linear_to_srgb if curve == "srgb" else (lambda v: v.clip(0.0, 1.0))
        self.size = int(np.prod(shape))
        self.bank = rng.standard_normal(3 * self.size, dtype=np.float32) if noise > 0 else None

    def __call__(self, img: np.ndarray) -> np.ndarray:
        import cv2

        if self.blur > 0:
            img = cv2.GaussianBlur(img, (0, 0), self.blur)
        if self.noise > 0:
            # shot noise grows with the signal (variance ~ signal), read noise does not
            var = np.clip(img, 0, 1)
            var *= np.float32(0.0004 * self.noise ** 2)
            var += np.float32((0.008 * self.noise) ** 2)
            off = int(self.rng.integers(0, 2 * self.size))
            img = img + np.sqrt(var) * self.bank[off:off + self.size].reshape(self.shape)
        u8 = np.clip(self.encode(img) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        return R.jpeg_roundtrip(u8, self.quality)


def _frame_count(duration: float | None, t_max: float, dt: float, what: str) -> int:
    """Frames for a requested duration (None: as long as the experiment lasts), refusing
    durations the experiment does not last."""
    dur = t_max if duration is None else duration
    if dur > t_max + 1e-9:
        raise FitodeError(f"{what} lasts {t_max:.3f} s; ask for a duration of at most that")
    n = int(np.floor(dur / dt + 1e-9))
    if dur >= t_max - 1e-9:
        n = int(np.floor(t_max / dt))  # frame n-1 is at or before t_max
    if n < 2:
        raise FitodeError(f"a duration of {dur:g} s at this fps gives fewer than 2 frames")
    return n


# --- backgrounds -------------------------------------------------------------------------

def _wall(rng, h, w, base=(0.78, 0.74, 0.66), light_from=(0.2, 0.0), texture=0.05) -> np.ndarray:
    """A painted wall: a seeded plaster texture and light falling off from one side."""
    tex = R.value_noise(rng, h, w, (6, 24, 90), (1.0, 0.5, 0.35))
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    d = np.hypot(x / w - light_from[0], y / h - light_from[1])
    light = 1.05 - 0.3 * d
    img = np.asarray(base, np.float32)[None, None] * (light * (1 + texture * tex))[..., None]
    return np.clip(img, 0, 1).astype(np.float32)


def _wood(rng, h, w, base=(0.55, 0.38, 0.22), along: str = "x") -> np.ndarray:
    """Wood-like grain: noise stretched along one axis."""
    if along == "x":
        g = R.value_noise(rng, h, max(w // 8, 4), (3, 10, 30))
        g = np.repeat(g, 8, axis=1)[:, :w]
        if g.shape[1] < w:
            g = np.pad(g, ((0, 0), (0, w - g.shape[1])), mode="edge")
    else:
        g = R.value_noise(rng, max(h // 8, 4), w, (20, 60))
        g = np.repeat(g, 8, axis=0)[:h]
        if g.shape[0] < h:
            g = np.pad(g, ((0, h - g.shape[0]), (0, 0)), mode="edge")
    grain = 1 + 0.12 * np.sin(6 * g) + 0.05 * R.value_noise(rng, h, w, (40, 120))
    return np.clip(np.asarray(base, np.float32)[None, None] * grain[..., None], 0, 1).astype(np.float32)


def _paste_rows(img: np.ndarray, y0: int, patch: np.ndarray) -> None:
    img[y0:y0 + patch.shape[0]] = patch[: img.shape[0] - y0]


def _rgb(*c: float) -> np.ndarray:
    return np.asarray(c, np.float32)


# --- pendulum ------------------------------------------------------------------------------

PENDULUM_EQUATION = "theta'' = -g/L*sin(theta) - zeta*theta'"


def pendulum_system():
    """The equation of the pendulum scene, g fixed at 9.80665."""
    from fitode.eqparse import parse

    return parse(PENDULUM_EQUATION)


def _pendulum(L, rng, duration, dt, h, w, p) -> _Scene:
    from fitode.synth.trajectory import simulate_system

    if not 0.05 <= L <= 20:
        raise FitodeError(f"pendulum length L must be between 0.05 and 20 m, got {L}")
    zeta = float(p.get("zeta", 0.05))
    theta0 = np.deg2rad(float(p.get("theta0_deg", rng.uniform(15.0, 35.0))))
    omega0 = float(p.get("omega0", 0.0))
    n = _frame_count(duration, np.inf, dt, "the pendulum")
    latent, names, state, snames = simulate_system(pendulum_system(), {"L": L, "zeta": zeta},
                                                   {"theta": theta0, "theta'": omega0}, n, dt, substeps=20)
    theta = latent[:, 0]
    bob_m = 0.035
    ppm = 0.8 * h / (L + bob_m)
    px, py = w / 2 + rng.uniform(-0.05, 0.05) * w, 0.1 * h
    rb = max(bob_m * ppm, 2.5)

    bg = _wall(rng, h, w)
    cv = R.Canvas(bg, 4)
    bar_h = max(0.025 * h, 3)
    cv.paint(R.box(w / 2, py - bar_h, w * 0.45, bar_h / 2, radius=1), _rgb(0.25, 0.25, 0.28),
             (0.05 * w - 2, py - 1.5 * bar_h, 0.95 * w + 2, py - bar_h / 2))
    cv.paint(R.box(px, py - bar_h / 2, 0.012 * h + 2, bar_h * 0.9, radius=1), _rgb(0.15, 0.15, 0.16),
             (px - 0.012 * h - 3, py - 2 * bar_h, px + 0.012 * h + 3, py + bar_h))
    # the wall's shadow of the bob: light from upper left, the bob 15 cm in front of the wall
    shadow = (0.03 * ppm, 0.02 * ppm)

    def draw(c: R.Canvas, i: int) -> None:
        bx, by = px + L * ppm * np.sin(theta[i]), py + L * ppm * np.cos(theta[i])
        sx, sy = bx + shadow[0], by + shadow[1]
        c.paint(R.circle(sx, sy, rb), 0.0, (sx - rb - 6, sy - rb - 6, sx + rb + 6, sy + rb + 6),
                opacity=0.3, soft=4.0)
        hw = max(0.0025 * ppm, 0.6)
        c.paint(R.segment(px, py, bx, by, hw), _rgb(0.12, 0.12, 0.12),
                (min(px, bx) - 2, min(py, by) - 2, max(px, bx) + 2, max(py, by) + 2))
        c.paint(R.circle(bx, by, rb), R.sphere_shade(bx, by, rb, (0.62, 0.64, 0.7)),
                (bx - rb, by - rb, bx + rb, by + rb))

    return _Scene(background=cv.image, draw=draw, latent=latent, latent_names=names,
                  truth={"L": L, "zeta": zeta},
                  physical={"g": G, "L": L, "zeta": zeta, "theta0_deg": float(np.rad2deg(theta0)),
                            "omega0": omega0, "pixels_per_metre": ppm, "substeps": 20},
                  state=state, state_names=snames)


# --- Torricelli ----------------------------------------------------------------------------

def _torricelli(k, rng, duration, dt, h, w, p) -> _Scene:
    if not 1e-4 <= k <= 1.0:
        raise FitodeError(f"Torricelli k must be between 1e-4 and 1 m^0.5/s, got {k}")
    h0 = float(p.get("h0", rng.uniform(0.20, 0.26)))
    tank_h, tank_w = 0.30, 0.10
    if not 0.01 <= h0 <= tank_h - 0.01:
        raise FitodeError(f"h0 must be between 0.01 and {tank_h - 0.01} m, got {h0}")
    # stop while a centimetre is left: below that the ball sits on the bottom
    t_max = 2 * (np.sqrt(h0) - np.sqrt(0.01)) / k
    n = _frame_count(duration, t_max, dt, "the tank (down to 1 cm)")
    t = np.arange(n) * dt
    level = (np.sqrt(h0) - k * t / 2) ** 2
    ppm = 0.62 * h / tank_h
    cx = 0.33 * w
    y_bot = 0.72 * h
    x_l, x_r = cx - tank_w / 2 * ppm, cx + tank_w / 2 * ppm
    y_top = y_bot - tank_h * ppm
    wall_t = max(0.004 * ppm, 1.5)
    ball_m = 0.015
    rb = ball_m * ppm
    drift = rng.uniform(0, 2 * np.pi)

    bg = _wall(rng, h, w, base=(0.72, 0.76, 0.8), light_from=(0.8, 0.0))
    table_y = int(round(y_bot + wall_t))
    _paste_rows(bg, table_y, _wood(rng, h - table_y, w))
    cv = R.Canvas(bg, 4)
    # a basin catching the jet
    cv.paint(R.box(0.78 * w, h - 0.03 * h, 0.12 * w, 0.03 * h + 2, radius=3), _rgb(0.3, 0.32, 0.36),
             (0.66 * w - 2, h - 0.07 * h, 0.9 * w + 2, h))
    # what is behind the tank looks slightly darker and greener through the glass
    cv.paint(R.box(cx, (y_top + y_bot) / 2, (x_r - x_l) / 2, (y_bot - y_top) / 2), _rgb(0.55, 0.62, 0.6),
             (x_l, y_top, x_r, y_bot), opacity=0.12)
    water = _rgb(0.22, 0.45, 0.75)
    glass = _rgb(0.85, 0.9, 0.92)

    def draw(c: R.Canvas, i: int) -> None:
        ys = y_bot - level[i] * ppm
        bx = cx + 0.25 * (x_r - x_l) * np.sin(0.3 * t[i] + drift)
        by = ys - 0.45 * rb
        c.paint(R.circle(bx, by, rb), R.sphere_shade(bx, by, rb, (0.95, 0.45, 0.1)),
                (bx - rb, by - rb, bx + rb, by + rb))
        c.paint(R.box(cx, (ys + y_bot) / 2, (x_r - x_l) / 2, (y_bot - ys) / 2),
                lambda x, y: water * (1 - 0.25 * np.clip((y - ys) / (tank_h * ppm), 0, 1))[..., None],
                (x_l, ys, x_r, y_bot), opacity=0.55)
        c.paint(R.box(cx, ys, (x_r - x_l) / 2, 0.6), _rgb(0.85, 0.92, 1.0), (x_l, ys - 2, x_r, ys + 2),
                opacity=0.6)
        # the jet: Torricelli's exit speed sqrt(2 g h), then a free parabola
        v = np.sqrt(2 * G * max(level[i], 0.0))
        ox, oy = x_r + wall_t, y_bot - 0.01 * ppm
        tt = np.linspace(0, 0.25, 24)
        xs = ox + v * tt * ppm
        yv = oy + 0.5 * G * tt ** 2 * ppm
        jr = max(0.0025 * ppm, 0.8)
        for a in range(len(tt) - 1):
            if yv[a] > h + 2 or xs[a] > w + 2:
                break
            c.paint(R.segment(xs[a], yv[a], xs[a + 1], yv[a + 1], jr), water,
                    (min(xs[a], xs[a + 1]) - jr, min(yv[a], yv[a + 1]) - jr,
                     max(xs[a], xs[a + 1]) + jr, max(yv[a], yv[a + 1]) + jr), opacity=0.7)

    def overlay(c: R.Canvas, i: int) -> None:
        for xw in (x_l - wall_t / 2, x_r + wall_t / 2):
            c.paint(R.box(xw, (y_top + y_bot) / 2, wall_t / 2, (y_bot - y_top) / 2), glass,
                    (xw - wall_t, y_top, xw + wall_t, y_bot), opacity=0.7)
        c.paint(R.box(cx, y_bot + wall_t / 2, (x_r - x_l) / 2 + wall_t, wall_t / 2), glass,
                (x_l - wall_t, y_bot, x_r + wall_t, y_bot + wall_t), opacity=0.8)
        # highlight streak on the front glass
        c.paint(R.box(x_l + 0.2 * (x_r - x_l), (y_top + y_bot) / 2, 1.0, 0.45 * (y_bot - y_top)),
                _rgb(1, 1, 1), (x_l, y_top, x_r, y_bot), opacity=0.25)
        c.paint(R.circle(x_r + wall_t, y_bot - 0.01 * ppm, 2.0), _rgb(0.2, 0.2, 0.22),
                (x_r, y_bot - 0.01 * ppm - 3, x_r + wall_t + 3, y_bot - 0.01 * ppm + 3))

    return _Scene(background=cv.image, draw=draw, overlay=overlay, latent=level[:, None],
                  latent_names=("h",), truth={"k": k},
                  physical={"k": k, "h0": h0, "tank_height": tank_h, "g": G, "pixels_per_metre": ppm,
                            "empty_after_s": float(2 * np.sqrt(h0) / k)},
                  state=level[:, None], state_names=("h",))


# --- sliding block -------------------------------------------------------------------------

def _sliding_block(alpha_deg, rng, duration, dt, h, w, p) -> _Scene:
    mu = float(p.get("mu", 0.21))
    alpha = np.deg2rad(alpha_deg)
    if not 1.0 <= alpha_deg <= 80.0:
        raise FitodeError(f"the ramp angle must be between 1 and 80 degrees, got {alpha_deg}")
    a = G * (np.sin(alpha) - mu * np.cos(alpha))
    if a <= 0.05:
        raise FitodeError(f"at alpha = {alpha_deg:g} deg and mu = {mu:g} the block does not slide "
                          f"(a = {a:.3f} m/s^2)")
    # rest_before, rest_after (seconds): held still at the top, then stopped at the end (a slide a
    # user films with its start and its stop in view, which the stretch finder cuts off)
    rest_before, rest_after = float(p.get("rest_before", 0.0)), float(p.get("rest_after", 0.0))
    t0 = float(p.get("t0", 0.0 if rest_before > 0 else rng.uniform(0.0, 0.1)))
    ramp, bl, bh, s0 = 1.0, 0.10, 0.06, 0.02
    t_max = np.sqrt(2 * (ramp - bl - s0) / a) - t0
    if t_max <= 2 * dt:
        raise FitodeError("t0 is too late: the block has already reached the bottom")
    n = _frame_count(duration, t_max, dt, "the slide down the ramp")
    t = np.arange(n) * dt
    s = s0 + 0.5 * a * (t + t0) ** 2
    v = a * (t + t0)
    before, after = int(round(rest_before / dt)), int(round(rest_after / dt))
    s = np.concatenate([np.full(before, s[0]), s, np.full(after, s[-1])])
    v = np.concatenate([np.zeros(before), v, np.zeros(after)])

    ppm = min(0.8 * w / (ramp * np.cos(alpha) + 0.15), 0.62 * h / (ramp * np.sin(alpha) + bh))
    floor_y = 0.86 * h
    x_bot = 0.5 * w + 0.5 * ramp * np.cos(alpha) * ppm
    x_top, y_top = x_bot - ramp * np.cos(alpha) * ppm, floor_y - ramp * np.sin(alpha) * ppm
    d = np.array([np.cos(alpha), np.sin(alpha)])     # down the incline, screen coordinates
    nrm = np.array([np.sin(alpha), -np.cos(alpha)])  # out of the incline surface

    bg = _wall(rng, h, w, base=(0.8, 0.8, 0.78), light_from=(0.1, 0.0))
    _paste_rows(bg, int(floor_y), _wood(rng, h - int(floor_y), w, base=(0.42, 0.36, 0.3)))
    cv = R.Canvas(bg, 4)
    tri = np.array([[x_top, y_top], [x_bot, floor_y], [x_top, floor_y]])
    wood = _wood(rng, h, w, base=(0.7, 0.55, 0.35))
    cv.paint(R.polygon(tri), lambda x, y: wood[np.clip(y.astype(int), 0, h - 1), np.clip(x.astype(int), 0, w - 1)],
             (x_top, y_top, x_bot, floor_y))
    edge = 1.2
    cv.paint(R.segment(x_top, y_top, x_bot, floor_y, edge), _rgb(0.35, 0.26, 0.16),
             (x_top - 2, y_top - 2, x_bot + 2, floor_y + 2))
    ruler = _ruler(cv, x_bot - 0.5 * ppm, x_bot, 0.08 * h, 0.5, max(2.0, 0.02 * h))
    body = _rgb(0.15, 0.35, 0.7)

    def draw(c: R.Canvas, i: int) -> None:
        centre = np.array([x_top, y_top]) + d * (s[i] + bl / 2) * ppm + nrm * (bh / 2 * ppm + edge)
        hw, hh = bl / 2 * ppm, bh / 2 * ppm
        rad = hw + hh + 2
        bbox = (centre[0] - rad, centre[1] - rad, centre[0] + rad, centre[1] + rad)
        sh = centre - nrm * 2.5
        c.paint(R.box(sh[0], sh[1], hw + 1, hh, alpha), 0.0, bbox, opacity=0.25, soft=3.0)

        def shade(x, y):
            # light from above: brighter towards the top face
            up = ((x - centre[0]) * nrm[0] + (y - centre[1]) * nrm[1]) / (hh + 1e-6)
            return body * (0.85 + 0.25 * np.clip(up, -1, 1))[..., None]
        c.paint(R.box(centre[0], centre[1], hw, hh, alpha, radius=1.0), shade, bbox)

    return _Scene(background=cv.image, draw=draw, latent=s[:, None], latent_names=("s",),
                  truth={"alpha": float(alpha), "mu": mu},
                  physical={"a": float(a), "alpha_deg": float(alpha_deg), "mu": mu, "g": G, "t0": t0,
                            "rest_before_frames": before, "rest_after_frames": after,
                            "s0": s0, "ramp_length": ramp, "pixels_per_metre": float(ppm), "ruler": ruler},
                  state=np.stack([s, v], axis=1), state_names=("s", "s'"))


# --- a fall with drag, side-on ---------------------------------------------------------------

def _drag_fall(k, rng, duration, dt, h, w, p) -> _Scene:
    """A light ball dropped from rest in front of a wall, filmed side-on from far away (no
    perspective: every point of the fall is at the same distance), quadratic air drag:
    y'' = g - k y'|y'| with y the distance fallen (down), terminal velocity sqrt(g/k)."""
    if not 0.001 <= k <= 10:
        raise FitodeError(f"k must be between 0.001 and 10 per metre, got {k}")
    vt = float(np.sqrt(G / k))
    rest = float(p.get("rest_before", 0.0))
    t_all = np.arange(_frame_count(duration, np.inf, dt, "the fall")) * dt
    t = np.clip(t_all - rest, 0.0, None)
    y = vt ** 2 / G * np.log(np.cosh(G * t / vt))
    v = vt * np.tanh(G * t / vt)
    r = 0.03
    ppm = 0.9 * h / (float(y[-1]) + 4 * r)
    bg = _wall(rng, h, w, base=(0.8, 0.79, 0.75), light_from=(0.5, 0.0))
    top = 2 * r * ppm
    ball = _rgb(0.75, 0.12, 0.1)

    def draw(c: R.Canvas, i: int) -> None:
        cx, cy, rr = 0.5 * w, top + y[i] * ppm, r * ppm
        c.paint(R.circle(cx, cy, rr), R.sphere_shade(cx, cy, rr, ball, light=(-0.3, -0.3, 0.9), specular=0.3),
                (cx - rr, cy - rr, cx + rr, cy + rr))

    return _Scene(background=bg, draw=draw, latent=y[:, None], latent_names=("y",), truth={"k": k},
                  physical={"k": k, "terminal_velocity": vt, "g": G, "pixels_per_metre": float(ppm),
                            "rest_before_frames": int(round(rest / dt))},
                  state=np.stack([y, v], axis=1), state_names=("y", "y'"))


# --- LED -----------------------------------------------------------------------------------

def _led(gamma, rng, duration, dt, h, w, p) -> _Scene:
    if not 0.001 <= gamma <= 100:
        raise FitodeError(f"gamma must be between 0.001 and 100 per second, got {gamma}")
    b0 = float(p.get("I0", rng.uniform(0.8, 0.95)))
    if not 0 < b0 <= 1:
        raise FitodeError(f"I0 (initial brightness) must be in (0, 1], got {b0}")
    n = _frame_count(duration, np.inf, dt, "the LED")
    t = np.arange(n) * dt
    b = b0 * np.exp(-gamma * t)

    # a dim lab: a green circuit board under weak ambient light
    board = R.value_noise(rng, h, w, (8, 30, 100), (1.0, 0.6, 0.4))
    bg = (_rgb(0.05, 0.12, 0.07)[None, None] * (1 + 0.25 * board)[..., None]).astype(np.float32)
    cv = R.Canvas(bg, 4)
    pitch = max(h / 18, 6)
    for yy in np.arange(pitch / 2, h, pitch):
        for xx in np.arange(pitch / 2, w, pitch):
            cv.paint(R.circle(xx, yy, 0.12 * pitch), _rgb(0.02, 0.04, 0.03), (xx - 3, yy - 3, xx + 3, yy + 3))
    cx, cy = w / 2 + rng.uniform(-0.05, 0.05) * w, h / 2 + rng.uniform(-0.05, 0.05) * h
    rl = 0.06 * h
    for sx in (-1, 1):  # the LED's legs and a resistor
        cv.paint(R.segment(cx + sx * 0.35 * rl, cy + rl, cx + sx * 0.35 * rl, cy + 3.5 * rl, 0.12 * rl),
                 _rgb(0.26, 0.26, 0.25), (cx - rl, cy, cx + rl, cy + 4 * rl))
    cv.paint(R.box(cx + 3 * rl, cy + 3.5 * rl, 1.2 * rl, 0.35 * rl, radius=0.3 * rl), _rgb(0.3, 0.24, 0.16),
             (cx + rl, cy + 3 * rl, cx + 5 * rl, cy + 4 * rl))
    cv.paint(R.circle(cx, cy, rl), R.sphere_shade(cx, cy, rl, (0.3, 0.04, 0.03), ambient=0.3, specular=0.1),
             (cx - rl, cy - rl, cx + rl, cy + rl))
    base = cv.image

    # the LED's light at full brightness: a saturated core, a halo and a broad wash
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((x + 0.5 - cx) ** 2 + (y + 0.5 - cy) ** 2) / (rl * rl)
    core = np.clip(1.2 - r2, 0, 1) ** 0.5
    halo = np.exp(-r2 / 3.0)
    wash = np.exp(-r2 / 40.0)
    light = (core[..., None] * _rgb(0.7, 0.45, 0.38) + halo[..., None] * _rgb(0.8, 0.16, 0.1)
             + wash[..., None] * _rgb(0.2, 0.04, 0.025))
    # keep every pixel of base + light below 0.95: the sensor stays linear (no clipping)
    scale = float(np.min((0.95 - base) / np.maximum(light, 1e-6)))
    light *= scale

    def draw(c: R.Canvas, i: int) -> None:
        c.image += np.float32(b[i]) * light

    return _Scene(background=base, draw=draw, latent=b[:, None], latent_names=("I",),
                  truth={"gamma": gamma, "c": 0.0},
                  physical={"gamma": gamma, "I0": b0}, state=b[:, None], state_names=("I",))


# --- free fall -----------------------------------------------------------------------------

def _free_fall(r0, rng, duration, dt, h, w, p) -> _Scene:
    if not 0.005 <= r0 <= 0.3:
        raise FitodeError(f"the ball radius r0 must be between 0.005 and 0.3 m, got {r0}")
    h0 = float(p.get("h0", 0.20))
    floor = float(p.get("floor", 1.5))
    if not r0 < h0 < floor - r0:
        raise FitodeError(f"need r0 < h0 < floor - r0 (r0 = {r0}, h0 = {h0}, floor = {floor})")
    f = 1451.0 * w / 1920.0
    t_max = np.sqrt(2 * (floor - r0 - h0) / G)
    n = _frame_count(duration, t_max, dt, "the fall to the floor")
    t = np.arange(n) * dt
    dist = h0 + 0.5 * G * t ** 2
    radius = r0 * f / dist
    ox, oy = rng.uniform(-0.02, 0.02, 2)  # the ball falls a little off the optical axis

    # the floor 'floor' metres below the camera: tiles of 30 cm
    tile = 0.3 * f / floor
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    gx, gy = (x + 0.5 - w / 2) / tile, (y + 0.5 - h / 2) / tile
    grout = np.minimum(np.abs(gx - np.round(gx)), np.abs(gy - np.round(gy))) * tile
    tone = 1 + 0.08 * R.value_noise(rng, h, w, (5, 20, 80))
    checker = (np.floor(gx) + np.floor(gy)) % 2
    bg = _rgb(0.62, 0.6, 0.56)[None, None] * (tone * (1 - 0.06 * checker))[..., None]
    gl = np.clip(1.5 - grout, 0, 1)[..., None]
    bg = (bg * (1 - gl) + gl * _rgb(0.35, 0.34, 0.32)).astype(np.float32)
    bg *= (0.9 + 0.1 * np.exp(-((x - w / 2) ** 2 + (y - h / 2) ** 2) / (0.5 * w) ** 2))[..., None]
    ball = (0.9, 0.75, 0.1)

    def draw(c: R.Canvas, i: int) -> None:
        cx, cy = w / 2 + f * ox / dist[i], h / 2 + f * oy / dist[i]
        r = radius[i]
        # a seam: the ball spins slowly as it falls
        ang = 0.8 * t[i]

        def col(xx, yy):
            shade = R.sphere_shade(cx, cy, r, ball, light=(-0.3, -0.3, 0.9), specular=0.35)(xx, yy)
            u, v = (xx - cx) / r, (yy - cy) / r
            seam = np.abs(np.sin(3 * np.arctan2(v, u) + ang) * np.sqrt(np.clip(1 - u * u - v * v, 0, 1))
                          - 0.4 * (u * np.cos(ang) + v * np.sin(ang)))
            return shade * (1 - 0.55 * np.clip(1 - seam / 0.06, 0, 1))[..., None]
        c.paint(R.circle(cx, cy, r), col, (cx - r, cy - r, cx + r, cy + r))

    return _Scene(background=bg, draw=draw, latent=dist[:, None], latent_names=("d",),
                  truth={"g": G},
                  physical={"g": G, "r0": r0, "h0": h0, "floor": floor, "f_px": f,
                            "radius_px_first": float(radius[0]), "radius_px_last": float(radius[-1])},
                  state=np.stack([dist, G * t], axis=1), state_names=("d", "d'"))


# --- spring --------------------------------------------------------------------------------

SPRING_EQUATION = "y'' = -w2*y - c*y'"


def _spring(w2, rng, duration, dt, h, w, p) -> _Scene:
    """A can hanging on a spring: it bounces (y, up, the damped oscillator), sways sideways (the
    spring swings about its hook, another frequency) and turns (its label goes round); a second
    object crosses the view behind it (a ball carried by someone walking past); with legs = 2, a
    person's two dark legs walk back and forth across the view behind it as well."""
    if not 1.0 <= w2 <= 400.0:
        raise FitodeError(f"the spring's w2 must be between 1 and 400 1/s^2, got {w2}")
    c = float(p.get("c", 0.08))
    amp = float(p.get("amplitude", rng.uniform(0.05, 0.07)))      # metres, first bounce
    sway = float(p.get("sway", 0.06))                              # metres, sideways
    omega_s = float(p.get("sway_omega", 0.62 * np.sqrt(w2)))       # rad/s, not the bounce's
    crossings = int(p.get("distractors", 1))
    legs = int(p.get("legs", 0))
    n = _frame_count(duration, np.inf, dt, "the spring")
    t = np.arange(n) * dt
    wd = np.sqrt(max(w2 - c * c / 4, 1e-9))
    # y(0) = amp, y'(0) = 0 of y'' = -w2 y - c y' (exact)
    y = amp * np.exp(-c * t / 2) * (np.cos(wd * t) + c / (2 * wd) * np.sin(wd * t))
    yv = -amp * w2 / wd * np.exp(-c * t / 2) * np.sin(wd * t)
    phase = rng.uniform(0, 2 * np.pi)
    xs = sway * np.exp(-0.03 * t) * np.sin(omega_s * t + phase)
    turn = rng.uniform(0, 2 * np.pi) + 0.9 * t  # the label goes round, radians

    ppm = 0.55 * h / 0.45   # the scene spans about 0.8 m of height
    hx, hy = w * (0.45 + rng.uniform(-0.03, 0.03)), 0.08 * h  # the hook
    rest = 0.28 * ppm                                           # hook to the can's top at rest
    can_w, can_h = 0.033 * ppm, 0.06 * ppm                      # half width, half height

    bg = _wall(rng, h, w, base=(0.74, 0.72, 0.7), light_from=(0.7, 0.0))
    floor_y = int(0.9 * h)
    _paste_rows(bg, floor_y, _wood(rng, h - floor_y, w, base=(0.45, 0.38, 0.3)))
    cv = R.Canvas(bg, 4)
    cv.paint(R.box(hx, hy - 0.02 * h, 0.2 * w, 0.012 * h + 1, radius=1), _rgb(0.3, 0.3, 0.32),
             (hx - 0.2 * w - 2, hy - 0.04 * h - 2, hx + 0.2 * w + 2, hy + 2))
    # the crossing object: a ball at hand height, across the whole frame in a few seconds, in
    # the clip's middle (and, with distractors = 2, back again near its end)
    span = w + 0.2 * w
    trips = [(0.35 * n * dt, 1.0)] + ([(0.75 * n * dt, -1.0)] if crossings > 1 else [])
    cross_s = 2.4
    dr = 0.05 * ppm
    dy = 0.8 * h

    # someone walking back and forth behind the can: two dark legs from the floor to above the can
    walk_x0, walk_s = rng.uniform(0.1, 0.9) * w, rng.uniform(0.25, 0.4) * w  # pixels, pixels/s
    leg_w, leg_top = 0.035 * w, 0.3 * h

    def draw(cc: R.Canvas, i: int) -> None:
        ti = t[i]
        if legs:
            # a triangle wave across the view; each leg swings about the hip, one forward, one back
            u = (walk_x0 + walk_s * ti) / (1.2 * w)
            hip = (-0.1 + 1.2 * (1 - abs(2 * (u % 1.0) - 1))) * w
            for k in range(legs):
                foot = hip + 0.06 * w * np.sin(2 * np.pi * 1.6 * ti + np.pi * k)
                cc.paint(R.segment(hip, leg_top, foot, floor_y, leg_w), _rgb(0.07, 0.07, 0.09),
                         (min(hip, foot) - leg_w - 2, leg_top - leg_w - 2, max(hip, foot) + leg_w + 2, floor_y + leg_w + 2))
        for start, sign in trips[:crossings]:
            u = (ti - start) / cross_s
            if 0 <= u <= 1:
                bx = (-0.1 * w + u * span) if sign > 0 else (1.1 * w - u * span)
                by = dy + 0.03 * h * np.sin(2 * np.pi * 2.2 * u)  # carried by someone walking
                cc.paint(R.circle(bx, by, dr), R.sphere_shade(bx, by, dr, (0.75, 0.2, 0.15)),
                         (bx - dr, by - dr, bx + dr, by + dr))
        cx = hx + xs[i] * ppm
        cy = hy + rest + can_h - y[i] * ppm  # image y down, the state y up
        top = cy - can_h
        coils = 14
        ks = np.linspace(0, 1, 2 * coils + 1)
        px = hx + (cx - hx) * ks + np.where(np.arange(len(ks)) % 2 == 1, 0.012 * ppm, 0.0) * np.where(
            np.arange(len(ks)) % 4 == 1, 1, -1)
        py = hy + (top - hy) * ks
        for a in range(len(ks) - 1):
            cc.paint(R.segment(px[a], py[a], px[a + 1], py[a + 1], 0.6), _rgb(0.35, 0.35, 0.38),
                     (min(px[a], px[a + 1]) - 2, min(py[a], py[a + 1]) - 2,
                      max(px[a], px[a + 1]) + 2, max(py[a], py[a + 1]) + 2))
        tilt = np.arctan2(cx - hx, top - hy) * -1.0

        def body(xx, yy):
            u = np.clip((xx - cx) / can_w, -1, 1)
            lit = 0.55 + 0.45 * np.sqrt(1 - u * u) * (0.8 - 0.2 * u)
            # the label: a band that goes round with the can
            ang = np.arcsin(u) + turn[i]
            band = (np.cos(ang) > 0.3) & (np.abs(yy - cy) < 0.6 * can_h)
            col = np.where(band[..., None], _rgb(0.75, 0.1, 0.08), _rgb(0.15, 0.25, 0.65))
            return col * lit[..., None]
        r = can_w + can_h + 2
        cc.paint(R.box(cx, cy, can_w, can_h, tilt, radius=1.0), body, (cx - r, cy - r, cx + r, cy + r))

    return _Scene(background=cv.image, draw=draw, latent=y[:, None], latent_names=("y",),
                  truth={"w2": float(w2), "c": c},
                  physical={"w2": float(w2), "c": c, "amplitude": amp, "sway": sway, "sway_omega": omega_s,
                            "distractors": crossings, "pixels_per_metre": float(ppm),
                            "period_s": float(2 * np.pi / wd)},
                  state=np.stack([y, yv], axis=1), state_names=("y", "y'"),
                  pixels=np.stack([hx + xs * ppm, hy + rest + can_h - y * ppm], axis=1) - 0.5)


# --- throw ---------------------------------------------------------------------------------

THROW_EQUATION = "y'' = -g"


def _ruler(cv, x1: float, x2: float, y: float, metres: float, tick: float) -> dict:
    """Two dark marks on the wall `metres` apart (render coordinates x1, x2 at height y), joined
    by a thin bar, as a ruler or tape in view: the record gives their centres in source pixels
    (centres at whole numbers, as --scale takes them) for a scale stick."""
    ink = _rgb(0.1, 0.1, 0.12)
    for x in (x1, x2):
        cv.paint(R.segment(x, y - tick, x, y + tick, 0.8), ink, (x - 3, y - tick - 3, x + 3, y + tick + 3))
    cv.paint(R.segment(x1, y, x2, y, 0.4), ink, (x1 - 2, y - 2, x2 + 2, y + 2))
    return {"p1": [x1 - 0.5, y - 0.5], "p2": [x2 - 0.5, y - 0.5], "metres": float(metres)}


def _throw(g, rng, duration, dt, h, w, p) -> _Scene:
    """A small ball thrown across the view: held still at the launch point (rest_before
    seconds), a parabola (x at constant speed, y'' = -g up), then still where it lands
    (rest_after). Filmed as a slow-motion phone does: give fps=240 and store the frames at 30.
    angle (degrees): the launch angle, which sets the flight's time over its range; a ruler
    half the range long hangs on the wall above (physical "ruler": its marks in source pixels)."""
    if not 0.5 <= g <= 50:
        raise FitodeError(f"g must be between 0.5 and 50 m/s^2, got {g}")
    span = float(p.get("range", 2.0))                    # metres across
    if p.get("angle") is not None:
        angle = float(p["angle"])
        if not 1.0 <= angle <= 80.0:
            raise FitodeError(f"the launch angle must be between 1 and 80 degrees, got {angle}")
        flight = float(np.sqrt(2 * span * np.tan(np.deg2rad(angle)) / g))
    else:
        flight = float(p.get("flight", 0.8))            # seconds in the air
    radius = float(p.get("radius", 0.011))               # metres
    rest_before, rest_after = float(p.get("rest_before", 0.1)), float(p.get("rest_after", 0.1))
    vx, vy = span / flight, g * flight / 2
    before, after = int(round(rest_before / dt)), int(round(rest_after / dt))
    inflight = int(np.floor(flight / dt + 1e-9)) + 1
    total = before + inflight + after
    n = total if duration is None else min(total, _frame_count(duration, np.inf, dt, "the throw"))
    tf = np.clip((np.arange(n) - before) * dt, 0.0, (inflight - 1) * dt)
    x = vx * tf
    y = vy * tf - 0.5 * g * tf ** 2
    vel = np.where((np.arange(n) >= before) & (np.arange(n) < before + inflight), vy - g * tf, 0.0)
    ppm = 0.8 * w / span
    ox, oy = 0.1 * w, 0.75 * h - rng.uniform(0, 0.05) * h
    if vy * vy / (2 * g) * ppm > 0.7 * h:
        ppm = 0.7 * h / (vy * vy / (2 * g))
    rb = max(radius * ppm, 0.8)

    bg = _wall(rng, h, w, base=(0.8, 0.78, 0.74), light_from=(0.3, 0.0))
    floor_y = int(oy + 3 * rb + 2)
    _paste_rows(bg, floor_y, _wood(rng, h - floor_y, w, base=(0.5, 0.42, 0.33)))
    cv = R.Canvas(bg, 4)
    ruler = _ruler(cv, ox + 0.25 * span * ppm, ox + 0.75 * span * ppm, 0.08 * h, 0.5 * span, max(2.0, 0.02 * h))

    def draw(cc: R.Canvas, i: int) -> None:
        bx, by = ox + x[i] * ppm, oy - y[i] * ppm
        cc.paint(R.circle(bx, by, rb), R.sphere_shade(bx, by, rb, (0.9, 0.35, 0.1)),
                 (bx - rb - 1, by - rb - 1, bx + rb + 1, by + rb + 1))

    return _Scene(background=cv.image, draw=draw, latent=y[:, None], latent_names=("y",),
                  truth={"g": float(g)},
                  physical={"g": float(g), "vx": vx, "vy": vy, "flight_s": flight, "range": span,
                            "radius_px": float(rb), "pixels_per_metre": float(ppm),
                            "flight_start_frame": before, "flight_end_frame": before + inflight,
                            "angle_deg": float(np.rad2deg(np.arctan2(vy, vx))), "ruler": ruler,
                            "x": x.tolist()},
                  state=np.stack([y, vel], axis=1), state_names=("y", "y'"))


# --- clips as they are filmed: a hold, a release, bounces -------------------------------------

def _scale_truth(a, b, metres: float) -> dict:
    """The scale a user reads off two marks in view (render coordinates a, b): their centres in
    source pixels and the distance between them in metres, in the plane of the motion, as the
    ruler of the other scenes records it, with the text --scale takes."""
    p1, p2 = [round(float(a[0]) - 0.5, 2), round(float(a[1]) - 0.5, 2)], [round(float(b[0]) - 0.5, 2),
                                                                          round(float(b[1]) - 0.5, 2)]
    return {"p1": p1, "p2": p2, "metres": float(metres),
            "text": f"{p1[0]:g},{p1[1]:g},{p2[0]:g},{p2[1]:g}={metres:g}"}


def _flights(x0: float, v0: float, a: float, e: float, bounces: int, t: np.ndarray):
    """Position and velocity at times t (t < 0: held at x0) of a thing thrown from x0 >= 0 with
    velocity v0 against a constant pull a toward x = 0, where it bounces back with restitution e,
    `bounces` times; and the times of the bounces and of the end of the last flight."""
    times, starts = [], []
    tt, x, v = 0.0, x0, v0
    for k in range(bounces + 1):
        land = (v + np.sqrt(v * v + 2 * a * x)) / a  # x + v s - a s^2 / 2 = 0
        starts.append((tt, x, v))
        tt += land
        times.append(tt)
        x, v = 0.0, e * (a * land - v)
    pos, vel = np.full(len(t), float(x0)), np.zeros(len(t))
    for (t0, xs, vs), t1 in zip(starts, times):
        m = (t >= t0) & (t < t1)
        s = t[m] - t0
        pos[m], vel[m] = xs + vs * s - 0.5 * a * s * s, vs - a * s
    pos[t >= times[-1]] = 0.0
    return pos, vel, times


def _held_pendulum(L, rng, duration, dt, h, w, p) -> _Scene:
    """A dark ball on a string too thin to see, the pivot above the frame: a hand holds it at
    theta0 for `hold` seconds, lets go and moves away; the ball swings from rest."""
    from fitode.synth.trajectory import simulate_system

    if not 0.05 <= L <= 20:
        raise FitodeError(f"pendulum length L must be between 0.05 and 20 m, got {L}")
    zeta = float(p.get("zeta", rng.uniform(0.01, 0.05)))
    theta0 = np.deg2rad(float(p.get("theta0_deg", rng.uniform(40.0, 60.0))))
    hold = float(p.get("hold", rng.uniform(1.0, 2.0)))
    if not (0 < theta0 < np.pi / 2 and hold >= 0):
        raise FitodeError("theta0_deg must be between 0 and 90 degrees and hold not negative")
    n = _frame_count(duration, np.inf, dt, "the pendulum")
    held = min(int(round(hold / dt)), n)
    swing, names, state, snames = simulate_system(pendulum_system(), {"L": L, "zeta": zeta},
                                                  {"theta": theta0, "theta'": 0.0}, max(n - held, 2), dt,
                                                  substeps=20)
    # a hand is never quite still: a slow wander of up to tremor_deg, gone (with its speed) at the release
    tremor = np.deg2rad(float(p.get("tremor_deg", rng.uniform(0.3, 1.0))))
    tt = np.arange(held) * dt
    taper = ((held * dt - tt) / max(held * dt, 1e-9)) ** 2
    f1, f2, ph = rng.uniform(0.4, 0.9), rng.uniform(1.2, 2.5), rng.uniform(0, 2 * np.pi, 2)
    wander = tremor * taper * (0.7 * np.sin(2 * np.pi * f1 * tt + ph[0]) + 0.3 * np.sin(2 * np.pi * f2 * tt + ph[1]))
    theta = np.concatenate([theta0 + wander, swing[:, 0]])[:n]
    omega = np.concatenate([np.gradient(wander, dt) if held > 1 else np.zeros(held), state[:, 1]])[:n]
    side = float(rng.choice([-1.0, 1.0]))
    theta, omega = side * theta, side * omega
    bob_m = 0.03
    # the swing fills the width, the lowest point near the bottom: the pivot is above the frame
    reach = rng.uniform(0.85, 0.95) * min(0.46 * w / np.sin(theta0), 0.8 * h / (1 - np.cos(theta0)))
    ppm = reach / L
    px, py = w / 2 + rng.uniform(-0.03, 0.03) * w, 0.84 * h - reach
    rb = max(bob_m * ppm, 3.0)

    bg = _wall(rng, h, w, base=(0.8, 0.78, 0.72))
    cv = R.Canvas(bg, 4)
    # tape marks on the wall, 20 cm apart, below the swing
    gap = 0.2 if 0.2 * ppm < 0.6 * w else 0.6 * w / ppm
    ma = (w / 2 - gap * ppm / 2, 0.95 * h)
    mb = (w / 2 + gap * ppm / 2, 0.95 * h)
    R.scale_marks(cv, ma, mb)
    skin = _rgb(0.78, 0.52, 0.4)
    size = 2.6 * rb
    speed = rng.uniform(0.6, 1.0) * h  # px/s: the hand is out of the frame in about a second

    def draw(c: R.Canvas, i: int) -> None:
        bx, by = px + L * ppm * np.sin(theta[i]), py + L * ppm * np.cos(theta[i])
        c.paint(R.segment(px, py, bx, by, 0.2), _rgb(0.2, 0.2, 0.2),
                (min(px, bx) - 2, min(py, by) - 2, max(px, bx) + 2, max(py, by) + 2), opacity=0.25)
        c.paint(R.circle(bx, by, rb), R.sphere_shade(bx, by, rb, (0.07, 0.07, 0.08), specular=0.3),
                (bx - rb, by - rb, bx + rb, by + rb))
        # the hand pinches the ball from outside and below, then draws back out of the view
        out = np.array([side * 0.8, 0.6])
        hx, hy = np.array([px + L * ppm * np.sin(theta[min(i, held - 1)] if held else 0.0),
                           py + L * ppm * np.cos(theta[min(i, held - 1)] if held else 0.0)]) + out * (0.95 * size + rb)
        away = max(0.0, (i - held) * dt)
        hx, hy = hx + out[0] * speed * away, hy + out[1] * speed * away
        r = 2 * size
        c.paint(R.hand(hx, hy, size, float(np.arctan2(-out[1], -out[0]))), skin, (hx - r, hy - r, hx + r, hy + r))

    return _Scene(background=cv.image, draw=draw, latent=theta[:, None], latent_names=("theta",),
                  truth={"L": L, "zeta": zeta},
                  physical={"g": G, "L": L, "zeta": zeta, "theta0_deg": float(np.rad2deg(side * theta0)),
                            "hold_s": held * dt, "release_frame": held, "pixels_per_metre": float(ppm),
                            "pivot_px": [float(px), float(py)], "substeps": 20,
                            "ruler": _scale_truth(ma, mb, gap)},
                  state=np.stack([theta, omega], axis=1), state_names=("theta", "theta'"))


def _bumper_cart(a, rng, duration, dt, h, w, p) -> _Scene:
    """A cart on a gentle incline held still, let go, rolling down into the bumper at the foot of
    the track and climbing again `bounces` times (restitution e): s'' = -a, s the distance up the
    track (x would be the horizontal, a cos of the incline)."""
    if not 0.05 <= a <= 5.0:
        raise FitodeError(f"the cart's acceleration a must be between 0.05 and 5 m/s^2, got {a}")
    e = float(p.get("restitution", rng.uniform(0.75, 0.9)))
    bounces = int(p.get("bounces", 5))
    track = 1.2
    x0 = float(p.get("x0", rng.uniform(0.7, 0.9) * track))
    rest_before = float(p.get("rest_before", rng.uniform(0.3, 0.8)))
    if not (0 < e <= 1 and bounces >= 0 and 0 < x0 <= track):
        raise FitodeError("restitution must be in (0, 1], bounces >= 0 and x0 on the track (0 to 1.2 m)")
    _, _, times = _flights(x0, 0.0, a, e, bounces, np.zeros(1))
    n = _frame_count(duration, rest_before + times[-1] - 2 * dt, dt, "the cart's flights")
    t = np.arange(n) * dt - rest_before
    x, v, _ = _flights(x0, 0.0, a, e, bounces, t)
    alpha = float(np.arcsin(min(a / G, 1.0)))
    shown = max(alpha, np.deg2rad(rng.uniform(2.5, 5)))  # drawn a little steeper than its pull: friction
    ppm = rng.uniform(0.8, 0.9) * w / (track + 0.15)
    bx0, by0 = 0.08 * w, 0.8 * h  # the bumper, at the foot of the track on the left
    d = np.array([np.cos(shown), -np.sin(shown)])  # up the track on screen
    nrm = np.array([-np.sin(shown), -np.cos(shown)])  # out of the track
    cl, ch = 0.1, 0.04
    bg = _wall(rng, h, w, base=(0.76, 0.78, 0.8), light_from=(0.6, 0.0))
    cv = R.Canvas(bg, 4)
    end = np.array([bx0, by0]) + d * (track + 0.1) * ppm
    cv.paint(R.segment(bx0, by0, end[0], end[1], 2.0), _rgb(0.45, 0.45, 0.48),
             (bx0 - 3, end[1] - 3, end[0] + 3, by0 + 3))
    cv.paint(R.box(bx0 - 3, by0 - 8, 3, 9, shown), _rgb(0.7, 0.1, 0.1), (bx0 - 12, by0 - 20, bx0 + 6, by0 + 4))
    gap = 0.5
    ma = np.array([bx0, by0]) + d * 0.3 * ppm - nrm * 6
    mb = ma + d * gap * ppm
    R.scale_marks(cv, tuple(ma), tuple(mb))
    body = _rgb(0.1, 0.3, 0.65)

    def draw(c: R.Canvas, i: int) -> None:
        centre = np.array([bx0, by0]) + d * (x[i] + cl / 2) * ppm + nrm * (ch / 2 * ppm + 3)
        r = (cl + ch) * ppm + 4
        c.paint(R.box(centre[0], centre[1], cl / 2 * ppm, ch / 2 * ppm, -shown, radius=1.0), body,
                (centre[0] - r, centre[1] - r, centre[0] + r, centre[1] + r))
        for k in (-0.3, 0.3):
            wx, wy = centre + d * k * cl * ppm - nrm * (ch / 2 * ppm + 1)
            c.paint(R.circle(wx, wy, 2.5), 0.05, (wx - 4, wy - 4, wx + 4, wy + 4))

    first = int(np.ceil(rest_before / dt))
    return _Scene(background=cv.image, draw=draw, latent=x[:, None], latent_names=("s",),
                  truth={"a": float(a)},
                  physical={"a": float(a), "a_px": float(a * ppm), "a_across_px": float(a * ppm * np.cos(shown)),
                            "shown_deg": float(np.rad2deg(shown)), "x0": x0, "rest_before_s": rest_before,
                            "restitution": e, "bounces": bounces,
                            "release_frame": first, "bounce_s": [rest_before + tb for tb in times[:-1]],
                            "alpha_deg": float(np.rad2deg(alpha)), "pixels_per_metre": float(ppm),
                            "ruler": _scale_truth(ma, mb, gap)},
                  state=np.stack([x, v], axis=1), state_names=("s", "s'"))


def _bouncing_ball(g, rng, duration, dt, h, w, p) -> _Scene:
    """A ball held still, dropped and bouncing `bounces` times off the floor (restitution e),
    seen side-on in front of a wall: y'' = -g, y up."""
    if not 0.5 <= g <= 50:
        raise FitodeError(f"g must be between 0.5 and 50 m/s^2, got {g}")
    e = float(p.get("restitution", rng.uniform(0.75, 0.9)))
    bounces = int(p.get("bounces", 4))
    drop = float(p.get("h0", rng.uniform(0.8, 1.0)))
    rest_before = float(p.get("rest_before", rng.uniform(0.3, 0.6)))
    radius = 0.03
    if not (0 < e <= 1 and bounces >= 0 and drop > 0):
        raise FitodeError("restitution must be in (0, 1], bounces >= 0 and h0 positive")
    _, _, times = _flights(drop, 0.0, g, e, bounces, np.zeros(1))
    n = _frame_count(duration, rest_before + times[-1] - 2 * dt, dt, "the ball's bounces")
    t = np.arange(n) * dt - rest_before
    y, v, _ = _flights(drop, 0.0, g, e, bounces, t)
    ppm = rng.uniform(0.75, 0.85) * h / (drop + 2 * radius)
    floor_y = 0.9 * h
    cx = w / 2 + rng.uniform(-0.1, 0.1) * w
    rb = radius * ppm
    bg = _wall(rng, h, w, base=(0.8, 0.79, 0.76), light_from=(0.2, 0.0))
    _paste_rows(bg, int(floor_y), _wood(rng, h - int(floor_y), w, base=(0.5, 0.42, 0.33)))
    cv = R.Canvas(bg, 4)
    gap = 0.5  # a ruler's two ends on the wall, half a metre apart, up the wall
    ma = (cx + 0.25 * w, floor_y - 0.1 * ppm)
    mb = (cx + 0.25 * w, floor_y - 0.6 * ppm)
    R.scale_marks(cv, ma, mb)

    def draw(c: R.Canvas, i: int) -> None:
        bx, by = cx, floor_y - (y[i] + radius) * ppm
        c.paint(R.circle(bx, by, rb), R.sphere_shade(bx, by, rb, (0.85, 0.3, 0.1)),
                (bx - rb - 1, by - rb - 1, bx + rb + 1, by + rb + 1))

    return _Scene(background=cv.image, draw=draw, latent=y[:, None], latent_names=("y",),
                  truth={"g": float(g)},
                  physical={"g": float(g), "g_px": float(g * ppm), "restitution": e, "bounces": bounces,
                            "release_frame": int(np.ceil(rest_before / dt)),
                            "bounce_s": [rest_before + tb for tb in times[:-1]], "h0": drop, "rest_before_s": rest_before,
                            "pixels_per_metre": float(ppm), "ruler": _scale_truth(ma, mb, gap)},
                  state=np.stack([y, v], axis=1), state_names=("y", "y'"))


def _sliding_puck(a, rng, duration, dt, h, w, p) -> _Scene:
    """A dark puck on a table seen from above: at rest, pushed by a hand (a smooth push of push_s
    seconds), sliding free until friction stops it (s'' = -a while it moves, s along its slide), then at rest: the
    slide ends where its velocity reaches zero, not at a wall. dot=1: a white sticker in its middle."""
    if not 0.1 <= a <= 6.0:
        raise FitodeError(f"the puck's deceleration a must be between 0.1 and 6 m/s^2, got {a}")
    rest_before = float(p.get("rest_before", rng.uniform(0.2, 0.5)))
    push = float(p.get("push_s", rng.uniform(0.08, 0.2)))
    rest_after = float(p.get("rest_after", rng.uniform(0.3, 0.8)))
    table = 1.0
    slide = float(p.get("slide", rng.uniform(0.45, 0.7) * table))  # metres from the push's end to the stop
    if not (rest_before >= 0 and push > 0 and rest_after >= 0 and 0.05 <= slide <= table):
        raise FitodeError("rest_before and rest_after must not be negative, push_s positive and slide "
                          f"between 0.05 and {table:g} m")
    v0 = float(np.sqrt(2 * a * slide))
    glide = v0 / a
    n = _frame_count(duration, rest_before + push + glide + rest_after, dt, "the puck's slide")
    t = np.arange(n) * dt - rest_before
    # the push: the velocity rises as (1 - cos) from 0 to v0 over `push` seconds
    x_push = 0.5 * v0 * push  # distance covered by the push (the mean of the cosine ramp is v0 / 2)
    x = np.zeros(n)
    v = np.zeros(n)
    m = (t > 0) & (t < push)
    u = t[m] / push
    v[m] = 0.5 * v0 * (1 - np.cos(np.pi * u))
    x[m] = 0.5 * v0 * (t[m] - push / np.pi * np.sin(np.pi * u))
    s = np.clip(t - push, 0.0, glide)
    m = t >= push
    x[m] = x_push + v0 * s[m] - 0.5 * a * s[m] ** 2
    v[m] = v0 - a * s[m]
    ppm = rng.uniform(0.75, 0.85) * w / (x_push + slide + 0.15)
    tilt = np.deg2rad(rng.uniform(-6, 6))  # the camera not quite square to the push
    d = np.array([np.cos(tilt), np.sin(tilt)])
    x0 = np.array([0.08 * w, rng.uniform(0.45, 0.6) * h])
    radius = 0.025 * ppm
    bg = _wood(rng, h, w, base=(0.62, 0.5, 0.36))
    cv = R.Canvas(bg, 4)
    gap = 0.5 if 0.5 * ppm < 0.8 * w else 0.25
    ma = (0.1 * w, 0.12 * h)
    mb = (0.1 * w + gap * ppm, 0.12 * h)
    R.scale_marks(cv, ma, mb)
    skin = _rgb(0.85, 0.62, 0.5)

    dot = bool(p.get("dot", 0))

    def draw(c: R.Canvas, i: int) -> None:
        cx, cy = x0 + d * x[i] * ppm
        box = (cx - radius - 1, cy - radius - 1, cx + radius + 1, cy + radius + 1)
        c.paint(R.circle(cx, cy, radius), _rgb(0.2, 0.2, 0.22), box)  # the rim, worn lighter
        c.paint(R.circle(cx, cy, 0.8 * radius), _rgb(0.06, 0.06, 0.07), box)
        if dot:  # a white sticker: its change is a ring about a light middle (docs/measured-paths.md)
            c.paint(R.circle(cx, cy, 0.45 * radius), 0.85, box)
        if t[i] < push:  # the hand behind the puck while it holds and pushes; gone once it lets go
            hx, hy = np.array([cx, cy]) - d * (radius + 0.9 * 2.2 * radius)
            size = 2.2 * radius
            c.paint(R.hand(hx, hy, size, float(tilt)), skin, (hx - 2.5 * size, hy - 2.5 * size, hx + 2.5 * size,
                                                               hy + 2.5 * size))

    return _Scene(background=cv.image, draw=draw, latent=x[:, None], latent_names=("s",),
                  truth={"a": float(a)},
                  physical={"a": float(a), "a_px": float(a * ppm), "v0": v0, "push_s": push, "slide": slide,
                            "rest_before_s": rest_before, "rest_after_s": rest_after,
                            "release_frame": int(np.ceil((rest_before + push) / dt)),
                            "stop_s": rest_before + push + glide, "tilt_deg": float(np.rad2deg(tilt)),
                            "pixels_per_metre": float(ppm), "ruler": _scale_truth(ma, mb, gap)},
                  state=np.stack([x, v], axis=1), state_names=("s", "s'"),
                  pixels=np.stack([x0[0] + d[0] * x * ppm - 0.5, x0[1] + d[1] * x * ppm - 0.5], axis=1))


@dataclass(frozen=True)
class SceneInfo:
    """One scene of the dataset: what it varies, how it is drawn, the equation it obeys."""

    name: str
    setting: str                 # the name of the varied quantity
    settings: tuple[float, ...]  # the dataset's values
    unit: str
    description: str
    default_duration: float | None  # None: as long as the experiment lasts
    params: tuple[str, ...]      # the scene-specific overrides `scene` accepts
    equation: str                # word for word that of the shipped equation file `system`
    system: str
    # (setting, rng, duration, dt, h, w, params) -> _Scene
    build: Callable[..., _Scene] = field(repr=False, compare=False)


SCENES: dict[str, SceneInfo] = {i.name: i for i in (
    SceneInfo("pendulum", "L", (0.45, 0.9, 1.5), "m",
              "a pendulum of length L swinging in front of a wall", 4.0,
              ("zeta", "theta0_deg", "omega0"), PENDULUM_EQUATION, "pendulum", _pendulum),
    SceneInfo("torricelli", "k", (0.0095, 0.0128, 0.0162), "m^0.5/s",
              "a draining tank, a floating ball marking the level", 5.0,
              ("h0",), "h' = -k*sqrt(h)", "torricelli", _torricelli),
    SceneInfo("sliding_block", "alpha", (20.0, 25.0, 30.0), "deg",
              "a block sliding down a ramp inclined at alpha (mu = 0.21)", None,
              ("mu", "t0", "rest_before", "rest_after"), "s'' = g*(sin(alpha) - mu*cos(alpha))", "sliding_block", _sliding_block),
    SceneInfo("led", "gamma", (2.3, 0.92, 0.46), "1/s",
              "an LED whose brightness decays as exp(-gamma t)", 3.0,
              ("I0",), "I' = -gamma*(I - c)", "led_decay", _led),
    SceneInfo("drag_fall", "k", (0.27, 0.1, 0.05), "1/m",
              "a light ball falling side-on with quadratic air drag (terminal velocity sqrt(g/k))", 1.2,
              ("rest_before",), "y'' = g - k*y'*abs(y')", "drag_fall", _drag_fall),
    SceneInfo("free_fall", "r0", (0.0335, 0.06, 0.10), "m",
              "a ball of radius r0 falling away from a camera looking down", None,
              ("h0", "floor"), "d'' = g", "free_fall_scale", _free_fall),
    SceneInfo("spring", "w2", (12.0, 18.0, 30.0), "1/s^2",
              "a can bouncing on a spring while it sways and turns, a ball carried across behind it", 12.0,
              ("c", "amplitude", "sway", "sway_omega", "distractors", "legs"), SPRING_EQUATION, "spring", _spring),
    SceneInfo("throw", "g", (1.62, 9.80665, 24.79), "m/s^2",  # the Moon, the Earth, Jupiter
              "a small ball thrown across the view (film it at 240 fps)", None,
              ("flight", "angle", "range", "radius", "rest_before", "rest_after"), THROW_EQUATION, "throw", _throw),
    SceneInfo("held_pendulum", "L", (0.45, 0.7, 1.2), "m",
              "a dark pendulum a hand holds at its starting angle, lets go and draws back", 10.0,
              ("zeta", "theta0_deg", "hold", "tremor_deg"), PENDULUM_EQUATION, "pendulum", _held_pendulum),
    SceneInfo("bumper_cart", "a", (0.3, 0.6, 1.2), "m/s^2",
              "a cart let go on an incline, bouncing off the bumper at its foot", None,
              ("restitution", "bounces", "x0", "rest_before"), "s'' = -a", "incline_cart", _bumper_cart),
    SceneInfo("bouncing_ball", "g", (1.62, 9.80665, 24.79), "m/s^2",
              "a ball held, dropped and bouncing on the floor", None,
              ("restitution", "bounces", "h0", "rest_before"), THROW_EQUATION, "throw", _bouncing_ball),
    SceneInfo("sliding_puck", "a", (0.5, 1.5, 3.0), "m/s^2",
              "a puck pushed by a hand across a table, sliding until friction stops it", None,
              ("rest_before", "push_s", "rest_after", "slide", "dot"), "s'' = -a", "incline_cart", _sliding_puck),
)}


def apparent_radius(v: SynthVideo) -> np.ndarray:
    """The free-fall ball's true apparent radius in pixels at each frame, r0 f / h."""
    ph = v.meta["physical"]
    return ph["r0"] * ph["f_px"] / v.latent[:, 0]
