"""Observation models: brightness decodes sRGB and reads the light linearly; auto picks it for a
decay whose frames dim as one; the choice is printed and can be overridden."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

import fitode
from fitode import cli, synth
from fitode.eqparse import parse
from fitode.train.observe import (BrightnessObservation, ObservationModel, PositionObservation, centroids, look,
                                  mend_one_way, resolve_observation)
from fitode.train.observe.light import linear_to_srgb, srgb_to_linear

DECAY = "I' = -gamma*I"


def test_srgb_round_trip_and_known_values():
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)
    assert srgb_to_linear(np.array(0.5)) == pytest.approx(0.2140, abs=1e-4)  # mid-grey is a fifth of the light
    t = torch.tensor([0.0, 0.02, 0.5, 1.0])
    torch.testing.assert_close(srgb_to_linear(t), torch.tensor([0.0, 0.02 / 12.92, 0.21404, 1.0]), atol=1e-5, rtol=0)


def _frames(kind: str, n: int = 40) -> torch.Tensor:
    """A dimming patch on a noisy background, or a bright square that moves across it."""
    rng = np.random.default_rng(0)
    out = np.empty((n, 1, 20, 30), dtype=np.float32)
    for i in range(n):
        img = 0.2 + 0.01 * rng.standard_normal((20, 30))
        if kind == "dim":
            img[5:15, 10:20] += 0.6 * np.exp(-0.05 * i)
        else:
            img[5:15, i % 20: i % 20 + 10] += 0.6
        out[i, 0] = img
    return torch.from_numpy(out)


def _disc(path, h=48, w=64, r=4.0, noise=0.02, seed=0) -> np.ndarray:
    """A bright disc at the given (x, y) centres (pixel i spans [i, i+1]) on a textured, noisy wall."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:h, :w]
    wall = 0.4 + 0.1 * np.sin(xx / 3.0) * np.cos(yy / 5.0) + 0.05 * rng.random((h, w))
    out = []
    for x, y in path:
        cover = np.clip(r + 0.5 - np.hypot(xx + 0.5 - x, yy + 0.5 - y), 0, 1)
        out.append(wall * (1 - cover) + 0.9 * cover + noise * rng.standard_normal((h, w)))
    return np.clip(np.array(out, dtype=np.float32), 0, 1)


def _decay_path(k=0.8, n=90, dt=1 / 30):
    t = np.arange(n) * dt
    return np.stack([8 + 60 * (1 - np.exp(-k * t)), 10 + 30 * (1 - np.exp(-k * t))], axis=1)


def test_centroids_follow_a_disc_that_slows_down_on_a_textured_wall():
    path = _decay_path()
    xy, pixels, unseen, _ = centroids(torch.from_numpy(_disc(path))[:, None])
    err = xy.numpy() - path
    err -= err.mean(axis=0)  # pixel-centre conventions differ by a constant
    assert np.abs(err).max() < 1.0 and unseen == 0 and 20 < pixels < 60  # the disc covers about 50 pixels


def test_auto_picks_position_brightness_or_any_from_a_look_at_the_frames():
    decay, osc = parse(DECAY), parse("x'' = -k*x")
    moving = torch.from_numpy(_disc(_decay_path()))[:, None]
    seen = look(moving)
    assert seen.moves and seen.one_way > 0.99 and seen.travel > 50
    assert not look(_frames("dim")).moves
    t = np.arange(90) / 30
    swinging = torch.from_numpy(_disc(np.stack([32 + 20 * np.sin(3 * t), 24 + 0 * t], axis=1)))[:, None]
    assert look(swinging).moves and look(swinging).one_way < 0.5
    picked = resolve_observation(None, decay, moving)
    assert isinstance(picked, PositionObservation) and "one way" in picked.reason
    assert isinstance(resolve_observation(None, osc, moving), PositionObservation)
    # back and forth: a state named for an image axis reads it; one that names none is left to an encoder
    assert isinstance(resolve_observation(None, osc, swinging), PositionObservation)
    assert type(resolve_observation(None, parse("q'' = -k*q"), swinging)) is ObservationModel
    dim = resolve_observation(None, decay, _frames("dim"))
    assert isinstance(dim, BrightnessObservation) and "stays in place" in dim.reason
    back_and_forth = resolve_observation("auto", decay, swinging)
    assert type(back_and_forth) is ObservationModel and "back and forth" in back_and_forth.reason
    assert type(resolve_observation(None, osc, _frames("dim"))) is ObservationModel
    mlp = resolve_observation(None, decay, _frames("dim"), encoder="mlp")
    assert type(mlp) is ObservationModel and "mlp encoder was asked for" in mlp.reason
    asked = resolve_observation("brightness", osc, None, light="linear")
    assert asked.light == "linear" and asked.reason == "brightness (as asked)"
    with pytest.raises(fitode.ConfigError, match="observation model 'shape'"):
        resolve_observation("shape", decay)


def test_brightness_decodes_the_pixels_and_refuses_values_it_cannot_decode():
    model = BrightnessObservation()
    x = torch.full((2, 1, 2, 2), 0.5)
    torch.testing.assert_close(model.decoded(x), torch.full_like(x, 0.21404), atol=1e-5, rtol=0)
    torch.testing.assert_close(model.decoded(x * 255), model.decoded(x))  # 8-bit values
    with pytest.raises(fitode.ConfigError, match="light='linear'"):
        model.decoded(x - 1)
    assert torch.equal(BrightnessObservation("linear").decoded(x - 1), x - 1)
    with pytest.raises(fitode.ConfigError, match="light"):
        BrightnessObservation("gamma")


def test_the_brightness_observation_needs_the_linear_encoder():
    frames = _frames("dim").numpy()
    with pytest.raises(fitode.ConfigError, match="encoder 'mlp' does not apply"):
        fitode.fit(frames, 0.1, eq=DECAY, observe="brightness", encoder="mlp", progress=False)
    with pytest.raises(fitode.ConfigError, match="light"):
        fitode.fit(frames, 0.1, eq=DECAY, light="gamma", progress=False)


def test_an_equation_file_names_its_observation(tmp_path):
    good = tmp_path / "lamp.toml"
    good.write_text('name = "lamp"\nequation = "I\' = -gamma*I"\nobserve = "any"\n')
    from fitode.eqfile import load_equation_file
    assert load_equation_file(good).observe == "any"
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "lamp"\nequation = "I\' = -gamma*I"\nobserve = "colour"\n')
    assert cli.main(["check", "--eq-file", str(bad)]) == 2


def test_check_names_the_observation_and_what_it_removes(capsys):
    assert cli.main(["check", "--eq", DECAY]) == 0
    out = capsys.readouterr().out
    assert "brightness where the change stays in place" in out and "I -> I**p" in out
    assert "auto -> position where the change moves one way" in out
    assert cli.main(["check", "--system", "led_decay"]) == 0
    assert "brightness (from the equation file)" in capsys.readouterr().out
    assert cli.main(["check", "--system", "pendulum"]) == 0
    assert "elsewhere any, as no constant follows a bend" in capsys.readouterr().out


def test_cli_refuses_a_free_encoder_with_the_brightness_observation(tmp_path, capsys):
    video = synth.write_video(synth.scene("led", gamma=0.92, size=(32, 40), duration=1.0, seed=1), tmp_path / "l.mp4")
    code = cli.main([str(video), "--eq", DECAY, "--observe", "brightness", "--encoder", "mlp",
                     "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "encoder 'mlp' does not apply" in err[0]


@pytest.mark.slow
def test_a_disc_sliding_to_rest_gives_its_rate_through_the_position_observation():
    # measured: k = 0.8181 for 0.8 (+2.3%), 95% [0.781, 0.854], trusted, fitted directly on frames
    # 0-80 (the encoder gave 0.8055); an exponential fitted to the centroids gives 0.822. The
    # promise a TRUSTED number makes is its interval
    frames = _disc(_decay_path(k=0.8))
    res = fitode.fit(frames, 1 / 30, eq="x' = -k*(x - c)", progress=False)
    assert res.meta["plan"]["observation"]["value"] == "position"
    lo, hi = res.parameters["k"].interval
    assert lo <= 0.8 <= hi and hi - lo < 0.25 * 0.8, (lo, hi)
    assert abs(res.values["k"] / 0.8 - 1) < 0.05, res.values
    verdict = res.verdicts["k"]
    _trusted_or_imprecise({**verdict, "verdict_reason": verdict["reason"], "value": res.values["k"],
                           "verdict_other_reasons": verdict.get("other_reasons", []), "interval": [lo, hi]}, 0.8)


def _within_99(p: dict, truth: float) -> bool:
    """The 99% interval (the 95% one widened about the value by Z99 / Z95, as the verdict reads it)
    holds the truth: what a number fitode does not call wrong promises."""
    v, (lo, hi), k = p["value"], p["interval"], 2.5758 / 1.9600
    return v - k * (v - lo) <= truth <= v + k * (hi - v)


def _trusted_or_imprecise(p: dict, truth: float) -> None:
    """TRUSTED, or short of it only because the clip pins the constant to more than the 5% a
    TRUSTED number promises at 99% (a small, short clip); the 99% interval holds the truth."""
    reasons = [p["verdict_reason"], *p.get("verdict_other_reasons", [])]
    assert p["verdict"] == "trusted" or (p["verdict"] == "ambiguous" and all("pins it only" in r for r in reasons)), p
    assert _within_99(p, truth), p


def test_the_position_observation_refuses_a_clip_where_nothing_moves():
    still = np.full((30, 16, 16), 0.3, dtype=np.float32)
    with pytest.raises(fitode.ConfigError, match="sees no change"):
        fitode.fit(still, 0.1, eq="x'' = -k*x", observe="position", progress=False)


@pytest.mark.slow
@pytest.mark.parametrize("eq, light", [(DECAY, None), ("I' = -gamma*(I - c)", "srgb")])
def test_an_led_decay_on_a_textured_noisy_board(tmp_path, capsys, eq, light):
    # a generated mp4: circuit-board texture, sensor noise, the sRGB curve, 8 bits, JPEG and then
    # H.264; 64x48, 3 s at 60 fps, a 68-frame window. Measured (this command line): gamma 0.8925
    # typed literally, truth 0.92; without the sRGB decoding (observe="any") 0.6798 (-26 %).
    # A glow stored as sRGB still changes as one pattern, so the frames cannot tell the curve:
    # with default flags the rate is not TRUSTED and the reason says so; told the curve, that doubt goes.
    v = synth.scene("led", gamma=0.92, size=(48, 64), seed=1)
    video = synth.write_video(v, tmp_path / "led.mp4")
    out = tmp_path / "run"
    flags = ["--light", light] if light else []
    assert cli.main([str(video), "--eq", eq, "--out", str(out), *flags]) == 0
    printed = capsys.readouterr().out
    assert "observation: brightness (auto" in printed and "decoded from sRGB" in printed
    report = json.loads((out / "result.json").read_text())
    gamma = report["parameters"]["gamma"]
    assert abs(gamma["value"] / 0.92 - 1) < 0.08, gamma
    if light:
        # told the curve, the light is no longer a doubt; this 64x48 clip pins gamma only to about
        # +-4% (95%), so the verdict may stay short of TRUSTED, but only for the clip's precision
        reasons = [gamma["verdict_reason"], *gamma.get("verdict_other_reasons", [])]
        assert not any("--light" in r or "curve" in r for r in reasons), gamma
        assert gamma["verdict"] == "trusted" or any("pins it only" in r for r in reasons), gamma
        assert _within_99(gamma, 0.92), gamma
    else:
        assert "light: srgb (assumed" in printed
        assert gamma["verdict"] == "ambiguous" and "--light" in gamma["verdict_reason"], gamma


def test_a_constant_that_changes_sign_with_the_state_is_compared_in_one_orientation():
    from fitode.eqparse.identify import sign_odd
    from fitode.train.result import RunRecord
    from fitode.train.trainer import _align
    assert sign_odd(parse("x'' = a")) == {"a"} and sign_odd(parse("x' = -k*(x - c)")) == {"c"}
    assert sign_odd(parse("x'' = -k*x - c*x'")) == set()
    t = np.linspace(0, 1, 20)
    latents = np.stack([t ** 2, -(t ** 2), t ** 2])[:, :, None]  # run 1 points the other way
    runs = [RunRecord(index=i, seed=i, init={}, final={"a": v, "k": 2.0}, loss=0.1, steps=1, status="ok")
            for i, v in enumerate([12.0, -11.5, 12.1])]
    _align(runs, latents, 0, {"a"})
    assert [r.value("a") for r in runs] == [12.0, 11.5, 12.1]
    assert [r.value("k") for r in runs] == [2.0, 2.0, 2.0] and runs[1].final["a"] == -11.5


def test_the_api_takes_the_equation_files_observation():
    frames = _frames("move").numpy()  # auto would not call this brightness
    res = fitode.fit(frames, 0.1, system="led_decay", restarts=1, max_steps=5, min_steps=5, progress=False)
    observation = res.meta["plan"]["observation"]
    assert observation["value"] == "brightness" and "from the equation file" in observation["reason"]
    res = fitode.fit(frames, 0.1, system="led_decay", observe="any", restarts=1, max_steps=5, min_steps=5,
                     progress=False)
    assert res.meta["plan"]["observation"]["value"] == "any"


def _scaled_disc(radii, centres, h=48, w=64, seed=0) -> np.ndarray:
    """A shaded disc of the given radii at the given centres on a textured, noisy wall, drawn at
    4x supersampling so its edge is anti-aliased."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:4 * h, :4 * w] / 4.0 + 0.125
    wall = 0.4 + 0.1 * np.sin(xx / 3.0) * np.cos(yy / 5.0)
    out = []
    for r, (cx, cy) in zip(radii, centres):
        rho = np.hypot(xx - cx, yy - cy)
        shade = 0.9 - 0.3 * (rho / r) ** 2
        img = np.where(rho < r, shade, wall).reshape(h, 4, w, 4).mean(axis=(1, 3))
        out.append(img + 0.01 * rng.standard_normal((h, w)))
    return np.clip(np.array(out, dtype=np.float32), 0, 1)[:, None]


def test_the_apparent_radius_of_a_disc_that_recedes_partly_outside_the_frame():
    from fitode.train.observe.extent import apparent_radii
    t = np.arange(40) / 40
    dist = 1 + 2 * t ** 2  # falling away: radius 30 -> 10 pixels, cut by the frame's top and bottom at first
    radii = 30 / dist
    centres = np.stack([32 + 6 / dist, 24 + 3 / dist], axis=1)  # a straight path in space: centre affine in r
    r, centre, unseen = apparent_radii(torch.from_numpy(_scaled_disc(radii, centres)))
    assert unseen == 0
    np.testing.assert_allclose(r.numpy(), radii, rtol=0.03)
    miss = np.linalg.norm(centre.numpy() + 0.5 - centres, axis=1)  # pixel i's centre is i + 0.5 here
    assert np.median(miss) < 0.3 and miss.max() < 1.5, miss


def _fall_radii(seed: int, folder: Path):
    """A generated ball falling away from the camera (135x240, H.264) read in colour at its source
    size: the true apparent radii, and per reading (the outline in colour, the ring of change alone
    in gray: the mean of the channels) the radii measured and g from a parabola through 1/r
    scaled by the true distances at the first and last frames (as a two-point --calibrate does)."""
    from fitode import api
    from fitode.pipeline import ReadOptions, read_clip
    from fitode.train.observe.extent import apparent_radii
    v = synth.scene("free_fall", 0.05, size=(135, 240), seed=seed)
    path = synth.write_video(v, folder / f"fall{seed}.mp4")
    clip, _ = read_clip(path, ReadOptions(size="240x135", color=True, stride=1))
    frames = api.as_frames(clip.frames)
    ph, idx = v.meta["physical"], clip.frame_indices
    dist, t = v.latent[idx, 0], idx / v.fps
    out = {}
    for name, seen in (("outline", frames), ("ring", frames.mean(dim=1, keepdim=True))):
        r = apparent_radii(seen)[0].numpy()
        d = dist[0] + (1 / r - 1 / r[0]) * (dist[-1] - dist[0]) / (1 / r[-1] - 1 / r[0])
        out[name] = (r, 2 * np.polyfit(t, d, 2)[0])
    return ph["r0"] * ph["f_px"] / dist, out


def test_the_outline_of_a_falling_ball_is_where_it_is_not_where_its_ring_of_change_leans(tmp_path):
    # the ring of change leans out where the ball's dark limb changes more than its face (g +2.2%,
    # +1.2%, +6.0% on these three, read in gray); its outline in colour: +0.2%, -0.5%, +0.9%
    outline, ring = [], []
    for seed in range(3):
        truth, read = _fall_radii(seed, tmp_path)
        assert np.sqrt(np.mean((read["outline"][0] / truth - 1) ** 2)) < 0.012
        outline.append(abs(read["outline"][1] / 9.80665 - 1))
        ring.append(abs(read["ring"][1] / 9.80665 - 1))
    assert max(outline) < 0.012 and np.mean(outline) < 0.3 * np.mean(ring), (outline, ring)


def test_a_lamp_read_again_in_colour_keeps_the_reason_for_its_stride(tmp_path):
    from fitode import api
    from fitode.pipeline import ReadOptions, light_in_colour, read_clip
    path = synth.write_video(synth.scene("led", 1.0, duration=2.0, seed=1), tmp_path / "led.mp4")
    req = api.requests(system="led_decay")[0]
    clip, t0 = read_clip(path)
    plan = api.plan(req, api.as_frames(clip.frames), clip.dt, track=clip.track)
    again = light_in_colour(path, ReadOptions(), req, clip, t0, plan)[0]
    assert again.frames.shape[1] == 3 and clip.frames.shape[1] == 1
    assert again.stride_reason == clip.stride_reason and "given by --stride" not in again.stride_reason
    assert again.track is clip.track


def test_a_size_is_read_again_in_colour_at_the_sources_size(tmp_path):
    from fitode import api
    from fitode.pipeline import ReadOptions, extent_in_detail, read_clip
    from fitode.train.observe import DistanceObservation
    v = synth.scene("free_fall", 0.05, size=(135, 240), seed=0)
    path = synth.write_video(v, tmp_path / "fall.mp4")
    req = api.requests(system="free_fall_scale")[0]
    clip, t0 = read_clip(path)
    plan = api.plan(req, api.as_frames(clip.frames), clip.dt, track=clip.track)
    assert isinstance(plan.observation, DistanceObservation) and clip.frames.shape[1:2] == (1,) and clip.frames.shape[2] == 64
    again, t1, replanned = extent_in_detail(path, ReadOptions(), req, clip, t0, plan)
    assert again.frames.shape[1:] == (3, *clip.source_size) and t1 == t0 and len(again.frames) == len(clip.frames)
    assert replanned.observation is plan.observation
    # the same frames: the stride's reason and the object's track are the first read's, said once
    assert again.stride_reason == clip.stride_reason and again.stride_reason.startswith("auto")
    assert again.track is clip.track and "read again at" in again.notes[-1]
    # frames the user sized are theirs
    given, _ = read_clip(path, ReadOptions(size="115x64"))
    assert extent_in_detail(path, ReadOptions(size="115x64"), req, given, t0, plan)[0] is given


def test_the_size_observation_warns_about_an_object_a_few_pixels_across():
    from fitode.train.observe import DistanceObservation, SizeObservation
    t = np.arange(30) / 30
    big = torch.from_numpy(_scaled_disc(12 - 6 * t, np.full((30, 2), [32.0, 24.0])))
    small = torch.from_numpy(_scaled_disc(5 - 3 * t, np.full((30, 2), [32.0, 24.0])))
    prepared = SizeObservation().prepare(big)
    assert prepared.caution is None and prepared.inputs.shape == (30, 1, 1, 1) and "apparent radius" in prepared.note
    radius = 12 - 6 * t

    def miss(z, x):  # rms residual of the best affine map from x to z
        return np.std(z - np.polyval(np.polyfit(x, z, 1), x))
    z = prepared.inputs.flatten().numpy()
    assert miss(z, radius) < 0.3 * miss(z, 1 / radius)  # size: affine in the radius
    z = DistanceObservation().prepare(big).inputs.flatten().numpy()
    assert miss(z, 1 / radius) < 0.3 * miss(z, radius)  # distance: affine in its reciprocal
    assert "pixels in radius at its smallest" in SizeObservation().prepare(small).caution
    with pytest.raises(fitode.ConfigError, match="no outline change"):
        SizeObservation().prepare(torch.full((20, 1, 16, 16), 0.3))


@pytest.mark.slow
def test_a_ball_falling_away_from_the_camera_gives_g_through_the_distance_observation(tmp_path, capsys):
    # the realistic free-fall scene (480x270 rendered, H.264, read at 64x114), calibrated with
    # the true distance at the first and last frames as a user would with a tape measure.
    # Measured (bench/realistic.py --scenes free_fall --videos 2): r0 0.06 m +1.3%, 0.1 m -1.6%.
    v = synth.scene("free_fall", 0.06, seed=0)
    video = synth.write_video(v, tmp_path / "fall.mp4")
    d, t_end = v.latent[:, 0], (v.n_frames - 1) / v.fps
    out = tmp_path / "run"
    assert cli.main([str(video), "--system", "free_fall_scale", "--out", str(out),
                     "--calibrate", f"d(0)={d[0]:.5f}; d({t_end:.6f})={d[-1]:.5f}"]) == 0
    printed = capsys.readouterr().out
    assert "observation: distance (from the equation file)" in printed and "read as its reciprocal" in printed
    g = json.loads((out / "result.json").read_text())["parameters"]["g"]
    assert abs(g["value"] / 9.80665 - 1) < 0.05, g
    _trusted_or_imprecise(g, 9.80665)


def test_check_names_the_distance_observation_of_the_free_fall_file(capsys):
    assert cli.main(["check", "--system", "free_fall_scale"]) == 0
    out = capsys.readouterr().out
    assert "distance (from the equation file)" in out and "f R / d" in out


@pytest.mark.slow
def test_a_fall_filmed_at_an_angle_is_trained_again_on_the_corrected_path():
    # a camera that looks up a wall sees a fall slow down: one homography of the path about its
    # middle, 8% at the ends. Read straight, one g misses the path; re-read, the latent is affine
    # in the distance fallen and g, calibrated by that affine map, is the one the disc fell with.
    n, dt, g = 50, 1 / 60, 230.0
    d = 0.5 * g * (np.arange(n) * dt) ** 2 + 8
    m = d.mean()
    seen = m + (d - m) / (1 - 0.08 / np.abs(d - m).max() * (d - m))
    frames = _disc(np.stack([np.full(n, 16.0), seen], axis=1), h=100, w=32, r=3.0)
    res = fitode.fit(frames, dt, eq="d'' = g", free=["g"], progress=False)
    assert res.meta["plan"]["observation"]["value"] == "position" and res.checks["perspective"]["apply"]
    assert "perspective" in res.meta["subspace"]
    slope = np.polyfit(res.latent[:, 0], d, 1)[0]
    assert abs(res.values["g"] * slope / g - 1) < 0.02, (res.values, slope)
    assert not any("whole clip" in f["reason"] for f in res.checks["findings"]), res.checks["findings"]


def test_a_hand_that_moves_at_the_edge_does_not_pull_the_centroid_of_a_falling_disc():
    n = 30
    path = np.stack([np.full(n, 16.0), 10 + 0.08 * np.arange(n) ** 2], axis=1)
    frames = _disc(path, h=100, w=32, r=3.0)
    frames[2 * n // 3:, 0:2, 0:4] = 0.95  # the edge of a hand pulled back at the top, in the last third
    xy, _, _, _ = centroids(torch.from_numpy(frames)[:, None])
    err = xy.numpy()[:, 1] - path[:, 1]
    assert np.abs(err - err.mean()).max() < 0.5


def test_a_one_way_path_is_mended_where_its_centroid_strays_and_an_oscillation_is_not():
    t = np.linspace(0, 1, 100)
    fall = torch.tensor(50 * t ** 2)
    strays = fall.clone()
    strays[40:48] += 20  # eight frames where the centroid of something else was taken
    mended, n = mend_one_way(strays)
    assert n == 8 and float((mended - fall).abs().max()) < 0.2
    noisy = fall + torch.tensor(0.3 * np.random.default_rng(0).standard_normal(100))
    assert mend_one_way(noisy)[1] == 0 and mend_one_way(fall)[1] == 0
    swing = torch.tensor(10 * np.sin(8 * t))
    swing[40] += 20
    assert mend_one_way(swing)[1] == 0  # a path that turns back is not its own running median


def test_restarts_that_read_one_measured_path_are_not_compared_in_their_own_units():
    from fitode.eqparse import analyse
    from fitode.train.observe import SizeObservation
    from fitode.train.trainer import _own_units
    system = parse("h' = -k*sqrt(h)")
    analysis = analyse(system)
    assert _own_units(system, analysis, PositionObservation()) == {"k"}
    assert _own_units(system, analysis, SizeObservation()) == {"k"}
    assert _own_units(system, analysis, ObservationModel()) == set()  # a free encoder's restarts are compared
    assert _own_units(parse("x'' = -w*x"), analyse(parse("x'' = -w*x")), PositionObservation()) == set()


def test_a_lamps_slow_tail_is_fitted_not_cut_as_a_stop(tmp_path):
    # a 16x16 glow decaying at 0.4/s for 4 s: its tail flattens for a frame at 1.3 s, which the
    # stretch search of a place takes for a stop (gamma 0.303 from the first 1.3 s, trusted)
    from fitode.examples.make_example import decay_values, render_glow, write_mp4
    video = write_mp4(tmp_path / "lamp.mp4", render_glow(decay_values(40, 10.0, 0.4), size=16, seed=0), 10.0)
    res = fitode.fit(video, eq="I' = -gamma*I", restarts=2, stride=1, light="linear", progress=False)
    stretch = res.meta["stretch"]
    assert (stretch["start_frame"], stretch["end_frame"]) == (0, 40) and "no stop" in stretch["reason"], stretch
    assert abs(res.values["gamma"] / 0.4 - 1) < 0.03, res.values
