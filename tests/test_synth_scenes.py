"""Realistic scenes: frame format, the physics of the latent, what the pixels show, truth files."""
import numpy as np
import pytest

from fitode import synth
from fitode.cli import main
from fitode.errors import FitodeError

G = 9.80665
SHORT = 0.25  # seconds: 15 frames at 60 fps keeps these tests fast


@pytest.mark.parametrize("name", list(synth.SCENES))
def test_scene_frames_truth_and_determinism(name, tmp_path):
    v = synth.scene(name, seed=3, duration=SHORT)
    assert v.frames.shape == (15, 270, 480, 3) and v.frames.dtype == np.uint8
    assert v.dt == pytest.approx(1 / 60) and v.fps == pytest.approx(60)
    assert v.latent.shape == (15, 1) and np.all(np.isfinite(v.latent))
    info = synth.SCENES[name]
    assert v.meta["setting"] == info.settings[1] and v.truth
    assert v.frames.std() > 5  # a textured picture, not a flat one
    x = v.as_tensor_frames()
    assert tuple(x.shape) == (15, 3, 270, 480) and float(x.max()) <= 1.0
    again = synth.scene(name, seed=3, duration=SHORT)
    assert np.array_equal(again.frames, v.frames)
    other = synth.scene(name, seed=4, duration=SHORT)
    assert not np.array_equal(other.frames, v.frames)
    p = synth.write_video(v, tmp_path / f"{name}.mp4")
    rec = synth.read_truth(p)
    assert rec["truth"] == pytest.approx(v.truth) and rec["fps"] == pytest.approx(60)
    assert rec["equation"] == v.equation and rec["settings"]["name"] == name
    assert rec["settings"]["physical"] and len(rec["latent"]) == 15


@pytest.mark.parametrize("name", list(synth.SCENES))
def test_scene_equation_is_the_shipped_files(name):
    from fitode.eqfile import load_system

    v = synth.scene(name, duration=0.05, size=(40, 64))
    spec = load_system(v.meta["system"])
    ode = spec.parse()
    assert spec.equation.strip() == v.equation
    assert set(v.truth) == set(ode.learnable) and v.latent_names == ode.states


def test_pendulum_obeys_the_nonlinear_equation():
    v = synth.scene("pendulum", 0.45, duration=1.5, size=(90, 160), theta0_deg=40.0)
    th, om = v.state[:, 0], v.state[:, 1]
    assert th[0] == pytest.approx(np.radians(40)) and om[0] == 0
    acc = np.gradient(om, v.dt)
    rhs = -G / 0.45 * np.sin(th) - 0.05 * om
    assert np.abs(acc - rhs)[1:-1].max() < 0.02 * np.abs(rhs).max()
    # nonlinear: the period at 40 degrees is longer than 2 pi sqrt(L/g)
    crossings = np.nonzero(np.diff(np.sign(th)))[0]
    half = (crossings[1] - crossings[0]) * v.dt
    assert half > 1.02 * np.pi * np.sqrt(0.45 / G)


def test_torricelli_level_follows_sqrt_law():
    v = synth.scene("torricelli", 0.0162, duration=2.0, size=(90, 160), h0=0.25)
    h = v.latent[:, 0]
    np.testing.assert_allclose(np.sqrt(h), np.sqrt(0.25) - 0.0162 * v.times / 2, atol=1e-12)
    dh = np.gradient(h, v.dt)
    np.testing.assert_allclose(dh[1:-1], -0.0162 * np.sqrt(h[1:-1]), rtol=1e-4)
    with pytest.raises(FitodeError, match="lasts"):
        synth.scene("torricelli", 0.0162, duration=100.0, h0=0.25)


@pytest.mark.parametrize("alpha", [20.0, 25.0, 30.0])
def test_sliding_block_acceleration(alpha):
    v = synth.scene("sliding_block", alpha, size=(90, 160))
    a = G * (np.sin(np.radians(alpha)) - 0.21 * np.cos(np.radians(alpha)))
    assert v.truth == {"alpha": pytest.approx(np.radians(alpha)), "mu": 0.21}
    assert v.meta["physical"]["a"] == pytest.approx(a)
    s = v.latent[:, 0]
    np.testing.assert_allclose(np.diff(s, 2) / v.dt ** 2, a, rtol=1e-6)
    # the default lasts the whole slide: the block ends near the bottom of the 1 m ramp
    assert 0.8 < s[-1] + 0.10 <= 1.0 + 1e-9


def test_a_pushed_puck_slides_with_x_dd_minus_a_and_stops_where_its_speed_is_zero():
    v = synth.scene("sliding_puck", 1.5, fps=120, size=(90, 160), seed=2)
    ph = v.meta["physical"]
    x, speed = v.state[:, 0], v.state[:, 1]
    t = np.arange(len(x)) * v.dt
    hold, free, stop = ph["rest_before_s"], ph["rest_before_s"] + ph["push_s"], ph["stop_s"]
    assert np.all(x[t < hold] == 0) and np.all(speed[t < hold] == 0)
    pushing = (t > hold + v.dt) & (t < free - v.dt)
    assert np.all(np.diff(speed[pushing]) > 0)  # the hand speeds it up
    gliding = np.flatnonzero((t > free + 2 * v.dt) & (t < stop - 2 * v.dt))
    np.testing.assert_allclose(np.diff(x[gliding], 2) / v.dt ** 2, -1.5, rtol=1e-6)
    assert x[-1] == pytest.approx(0.5 * ph["v0"] * ph["push_s"] + ph["slide"])
    assert np.all(speed[t >= stop] == 0) and np.all(x[t >= stop] == x[-1])
    px = v.pixels
    assert np.linalg.norm(px[-1] - px[0]) == pytest.approx(x[-1] * ph["pixels_per_metre"], rel=1e-9)


def test_led_pixels_are_affine_in_brightness():
    v = synth.scene("led", 2.3, duration=1.0)
    b = v.latent[:, 0]
    np.testing.assert_allclose(b, b[0] * np.exp(-2.3 * v.times), rtol=1e-12)
    # the camera stores the sRGB curve of the light: decoded pixels are affine in the brightness,
    # the stored ones are not
    from fitode.video.light import srgb_to_linear
    stored = v.frames[..., 0].reshape(v.n_frames, -1).astype(np.float64) / 255.0
    light, raw = srgb_to_linear(stored).mean(axis=1), stored.mean(axis=1)
    assert np.polyfit(b, light, 1)[0] > 0 and np.corrcoef(b, light)[0, 1] > 0.999
    residual = lambda y: np.std(y - np.polyval(np.polyfit(b, y, 1), b)) / np.std(y)  # noqa: E731
    assert residual(raw) > 3 * residual(light)
    assert v.frames.max() < 250  # nothing saturates


def test_free_fall_radius_seen_in_the_frames():
    v = synth.scene("free_fall", 0.06, seed=1)
    h = v.latent[:, 0]
    np.testing.assert_allclose(np.diff(h, 2) / v.dt ** 2, G, rtol=1e-6)
    f = 1451.0 * 480 / 1920
    r_true = 0.06 * f / h
    np.testing.assert_allclose(synth.apparent_radius(v), r_true)
    assert r_true[0] == pytest.approx(0.06 * f / 0.2)
    # the ball is the only saturated yellow thing: red and green well above blue
    img = v.frames.astype(np.int16)
    ball = (img[..., 0] - img[..., 2] > 60) & (img[..., 1] - img[..., 2] > 40)
    r_seen = np.sqrt(ball.reshape(v.n_frames, -1).sum(axis=1) / np.pi)
    np.testing.assert_allclose(r_seen[r_true < 60], r_true[r_true < 60], rtol=0.06)
    with pytest.raises(FitodeError, match="floor"):
        synth.scene("free_fall", 0.06, duration=2.0)


def test_setting_by_name():
    v = synth.scene("sliding_block", alpha=30.0, size=(90, 160), duration=0.1)
    assert v.meta["setting"] == 30.0 and v.meta["physical"]["alpha_deg"] == 30.0
    with pytest.raises(FitodeError, match="once"):
        synth.scene("sliding_block", 25.0, alpha=30.0)


def test_scene_refuses_bad_input():
    with pytest.raises(FitodeError, match="unknown scene"):
        synth.scene("rocket")
    with pytest.raises(FitodeError, match="no parameter"):
        synth.scene("led", colour=1.0)
    with pytest.raises(FitodeError, match="does not slide"):
        synth.scene("sliding_block", 5.0)
    with pytest.raises(FitodeError, match="size"):
        synth.scene("led", size=(10, 10))


def test_cli_scene(tmp_path, capsys):
    out = tmp_path / "led.npy"
    assert main(["synth", "scene", "led", "--setting", "0.46", "--duration", "0.2", "--size", "160x90",
                 "--out", str(out)]) == 0
    frames = np.load(out)
    assert frames.shape == (12, 90, 160, 3) and frames.dtype == np.uint8
    rec = synth.read_truth(out)
    assert rec["truth"] == {"gamma": 0.46, "c": 0.0} and rec["settings"]["size"] == [90, 160]
    assert "gamma = 0.46" in capsys.readouterr().out
    assert main(["synth", "scene", "led", "--out", str(out)]) == 2


def test_spring_scene_knows_where_its_can_is_and_draws_legs_behind_it():
    from fitode.synth.scenes import scene

    plain = scene("spring", 18.0, seed=3, fps=10.0, duration=1.0, size=(120, 160), distractors=0)
    legs = scene("spring", 18.0, seed=3, fps=10.0, duration=1.0, size=(120, 160), distractors=0, legs=2)
    assert legs.pixels.shape == (legs.n_frames, 2)
    np.testing.assert_allclose(legs.pixels, plain.pixels)
    gray = legs.frames.astype(float).mean(axis=3)
    for i, (x, y) in enumerate(np.round(legs.pixels).astype(int)):
        assert gray[i, y, x] < gray[i, 5, 5] - 30  # the can, darker than the wall, where the truth says
    # the legs: much darker pixels than anything in the plain scene, and only there
    assert (gray < plain.frames.astype(float).mean(axis=3).min() - 20).any()
