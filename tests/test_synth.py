"""fitode.synth: the paper's datasets, rendered equations, writing, the `fitode synth` command."""
import json

import cv2
import numpy as np
import pytest

from fitode import synth
from fitode.cli import main
from fitode.errors import FitodeError
from fitode.synth import paper, render
from fitode.synth.trajectory import damped_oscillator

G0, G1 = 4.0016, 0.08


# --- closed form ------------------------------------------------------------------------------

@pytest.mark.parametrize("g0,g1", [(4.0016, 0.08), (1.0, 2.0), (1.0, 3.0), (-0.5, 0.1)])
def test_damped_oscillator_solves_its_equation(g0, g1):
    t = np.linspace(0, 6, 6001)
    z, v = damped_oscillator(t, g0, g1, 0.7, -0.3)
    assert z[0] == pytest.approx(0.7) and v[0] == pytest.approx(-0.3)
    h = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(z, h)[1:-1], v[1:-1], atol=1e-4 * max(1, np.abs(v).max()))
    acc = np.gradient(v, h)
    resid = acc + g1 * v + g0 * z
    assert np.abs(resid[2:-2]).max() < 1e-4 * max(1, np.abs(acc).max())


def test_paper_latent_is_the_papers_cosine():
    v = synth.paper_video("intensity", n_frames=60)
    t = np.arange(60) * 0.2
    np.testing.assert_allclose(v.latent[:, 0], np.exp(-0.04 * t) * np.cos(2 * t), atol=1e-12)
    zdot = -np.exp(-0.04 * t) * (0.04 * np.cos(2 * t) + 2 * np.sin(2 * t))
    np.testing.assert_allclose(v.state[:, 1], zdot, atol=1e-12)
    assert v.truth == {"g0": G0, "g1": G1} and v.dt == 0.2 and v.fps == pytest.approx(5.0)


@pytest.mark.parametrize("kind", synth.PAPER_KINDS)
def test_paper_video_shape_range_and_tensor(kind):
    v = synth.paper_video(kind, n_frames=30, size=50)
    assert v.frames.shape == (30, 50, 50) and v.frames.dtype == np.float32
    assert v.frames.min() >= 0 and v.frames.max() <= 1 and v.frames.max() > 0.5
    assert v.latent.shape == (30, 1) and v.equation == "z'' + g1*z' + g0*z = 0"
    x = v.as_tensor_frames()
    assert tuple(x.shape) == (30, 1, 50, 50) and str(x.dtype) == "torch.float32"
    assert not np.array_equal(v.frames[0], v.frames[1])


def test_paper_defaults_span_54_seconds_at_dt_02():
    v = synth.paper_video("scale")
    assert v.n_frames == 270 and v.dt == 0.2


# --- what each rendering shows ---------------------------------------------------------------------

def test_intensity_gray_level_is_linear_in_z():
    v = synth.paper_video("intensity", n_frames=80)
    z = v.latent[:, 0]
    cov = paper.shape_coverage(50, 0)
    inside = cov == 1.0
    assert inside.sum() > 300
    # every fully covered pixel has exactly the gray level 0.6 + 0.4 z
    np.testing.assert_allclose(v.frames[:, inside].astype(np.float64).mean(axis=1), 0.6 + 0.4 * z, atol=1e-6)
    assert np.ptp(v.frames[:, inside], axis=1).max() == 0
    total = v.frames.reshape(80, -1).sum(axis=1)
    slope, icpt = np.polyfit(z, total, 1)
    assert np.abs(total - (slope * z + icpt)).max() < 1e-3 * total.max()
    assert icpt / slope == pytest.approx(0.6 / 0.4, rel=1e-4)
    assert 0.2 - 1e-6 <= v.frames[:, inside].min() and v.frames[:, inside].max() <= 1.0 + 1e-6


def _pendulum_angle(frame: np.ndarray) -> float:
    """Angle (degrees) of the intensity centroid about the pivot at the frame centre."""
    h, w = frame.shape
    y, x = np.mgrid[0:h, 0:w] + 0.5
    m = frame.sum()
    cx, cy = (frame * x).sum() / m, (frame * y).sum() / m
    return float(np.degrees(np.arctan2(cx - w / 2, cy - h / 2)))


def test_motion_centroid_angle_tracks_z():
    v = synth.paper_video("motion", n_frames=60)
    angles = np.array([_pendulum_angle(f) for f in v.frames])
    np.testing.assert_allclose(angles, 120.0 * v.latent[:, 0], atol=0.5)
    assert angles.max() > 110  # it really swings to about +-120 degrees


def test_scale_half_radii_track_z():
    v = synth.paper_video("scale", n_frames=60)
    z = v.latent[:, 0]
    left = v.frames[:, :, :25].reshape(60, -1).sum(axis=1)
    right = v.frames[:, :, 25:].reshape(60, -1).sum(axis=1)
    r_left, r_right = np.sqrt(2 * left / np.pi), np.sqrt(2 * right / np.pi)
    np.testing.assert_allclose(r_left, 10 * (1 + z), atol=0.05)
    np.testing.assert_allclose(r_right, 10 * (1 - z), atol=0.05)


def test_subpixel_motion_changes_the_frame():
    a = paper.pendulum_frame(0.3, 50)
    b = paper.pendulum_frame(0.3 + 0.1 / 20, 50)  # the bob moves 0.1 px
    assert np.abs(a - b).max() > 0.01
    # the area of a circle grows by 2 pi r dr for a 0.05 px larger radius
    cv1, cv2_ = render.Canvas(np.zeros((50, 50), np.float32)), render.Canvas(np.zeros((50, 50), np.float32))
    cv1.paint(render.circle(25.3, 24.8, 10.0), 1.0)
    cv2_.paint(render.circle(25.3, 24.8, 10.05), 1.0)
    grown = float(cv2_.image.sum() - cv1.image.sum())
    assert grown == pytest.approx(2 * np.pi * 10.0 * 0.05, rel=0.1)
    assert cv1.image.sum() == pytest.approx(np.pi * 100, rel=2e-3)


def test_edge_band_supersampling_equals_full_supersampling():
    sdf = render.intersect(render.star_blob(25, 25, 14, np.array([0.1, 0.07]), np.array([0.3, 2.0])),
                           render.half_plane(1, 0.3, 27, 25))
    x, y = render.pixel_centres(0, 0, 50, 50, 4)
    full = render.area_downsample(np.clip(0.5 - sdf(x, y) * 4, 0, 1), 4)
    np.testing.assert_allclose(render.coverage(sdf, 0, 0, 50, 50, 4), full, atol=1e-6)


def test_paper_noise_is_seeded():
    a = synth.paper_video("motion", n_frames=5, noise=0.05, seed=1).frames
    b = synth.paper_video("motion", n_frames=5, noise=0.05, seed=1).frames
    c = synth.paper_video("motion", n_frames=5, noise=0.05, seed=2).frames
    assert np.array_equal(a, b) and not np.array_equal(a, c)


@pytest.mark.parametrize("kwargs,match", [({"kind": "colour"}, "unknown rendering"),
                                          ({"n_frames": 1}, "at least 2 frames"),
                                          ({"dt": 0.0}, "dt must be"), ({"size": 4}, "size")])
def test_paper_refuses_bad_arguments(kwargs, match):
    kind = kwargs.pop("kind", "motion")
    with pytest.raises(FitodeError, match=match):
        synth.paper_video(kind, **kwargs)


# --- any equation -----------------------------------------------------------------------------

def test_render_equation_follows_the_closed_form_with_rk4():
    v = synth.render_equation("z'' + g1*z' + g0*z = 0", constants={"g0": G0, "g1": G1},
                              y0={"z": 1.0, "z'": -0.04}, n_frames=100, mode="scale")
    z, zd = damped_oscillator(v.times, G0, G1, 1.0, -0.04)
    np.testing.assert_allclose(v.latent[:, 0], z, atol=1e-6)
    np.testing.assert_allclose(v.state[:, 1], zd, atol=1e-6)
    assert v.truth == {"g0": G0, "g1": G1} and v.state_names == ("z", "z'")
    # the automatic mapping puts the trajectory's range on [-1, 1]: both half radii reach 0 and 20 px
    right = np.sqrt(2 * v.frames[:, :, 25:].reshape(100, -1).sum(axis=1) / np.pi)
    assert right.max() == pytest.approx(20, abs=0.1) and right.min() == pytest.approx(0, abs=0.1)


def test_render_equation_several_states_side_by_side():
    v = synth.render_equation("u' = a*u - b*u*w; w' = -c*w + d*u*w",
                              constants={"a": 1.0, "b": 0.5, "c": 1.0, "d": 0.3},
                              y0={"u": 2.0, "w": 1.0}, n_frames=40, dt=0.1, mode="intensity", size=32)
    assert v.frames.shape == (40, 32, 64) and v.latent.shape == (40, 2) and v.latent_names == ("u", "w")
    # each panel's brightness follows its own state
    for j in range(2):
        total = v.frames[:, :, 32 * j:32 * (j + 1)].reshape(40, -1).sum(axis=1)
        assert np.corrcoef(total, v.latent[:, j])[0, 1] > 0.999


def test_render_equation_explicit_mapping_pendulum_angle():
    # offset 0, scale 120 deg in radians: the drawn angle is the state itself
    v = synth.render_equation("theta'' = -g/L*sin(theta)", constants={"L": 1.0}, y0={"theta": 1.2},
                              n_frames=30, dt=0.1, mode="motion", mapping={"theta": (0.0, np.radians(120))})
    angles = np.array([_pendulum_angle(f) for f in v.frames])
    np.testing.assert_allclose(angles, np.degrees(v.latent[:, 0]), atol=0.5)
    assert v.meta["fixed"]["g"] == pytest.approx(9.80665)


def _shipped():
    from fitode.eqfile import list_systems

    return list_systems()


@pytest.mark.parametrize("name", _shipped())
def test_every_shipped_equation_renders(name):
    from fitode.eqfile import load_system

    spec = load_system(name)
    ode = spec.parse()
    consts = {k: (p.init if p.init is not None else 1.0) for k, p in spec.parameters.items()}
    y0 = {s: 0.5 + 0.3 * i for i, s in enumerate(ode.states)}  # distinct: the two bodies must not coincide
    for mode in synth.MODES:
        v = synth.render_equation(name, constants=consts, y0=y0, n_frames=40, dt=0.025, mode=mode, size=24)
        assert v.frames.shape == (40, 24, 24 * ode.dim) and np.all(np.isfinite(v.frames))
        assert v.latent.shape == (40, ode.dim) and np.ptp(v.latent) > 0
        assert v.meta["system"] == name and set(v.truth) == set(ode.learnable)
        assert v.frames.min() >= 0 and v.frames.max() <= 1


@pytest.mark.parametrize("constants,y0,match", [({"k": 1.0}, {"x": 1.0}, "constant"),
                                                ({"k": 1.0, "c": 0.1}, {"y": 1.0}, "not in the state"),
                                                ({"k": 1.0, "c": 0.1}, {"x'": 1.0}, "initial value"),
                                                ({"k": 1.0, "c": 0.1, "q": 2.0}, {"x": 1.0}, "q")])
def test_render_equation_refuses_incomplete_input(constants, y0, match):
    with pytest.raises(FitodeError, match=match):
        synth.render_equation("x'' = -k*x - c*x'", constants=constants, y0=y0, n_frames=10)


def test_render_equation_refuses_blow_up():
    with pytest.raises(FitodeError):
        synth.render_equation("x' = a*x^2", constants={"a": 1.0}, y0={"x": 1.0}, n_frames=50, dt=0.1)


# --- writing ------------------------------------------------------------------------------

def test_write_npy_keeps_frames_exactly_and_truth(tmp_path):
    v = synth.paper_video("intensity", n_frames=12)
    p = synth.write_video(v, tmp_path / "clip.npy")
    assert np.array_equal(np.load(p), v.frames)
    rec = synth.read_truth(p)
    assert rec == json.loads((tmp_path / "clip.truth.json").read_text())
    assert rec["truth"] == {"g0": G0, "g1": G1} and rec["dt"] == 0.2 and rec["fps"] == 5.0
    assert rec["equation"] == v.equation and rec["settings"]["kind"] == "intensity"
    np.testing.assert_allclose(np.array(rec["latent"]), v.latent)


def test_write_mp4_round_trips_through_opencv(tmp_path):
    v = synth.paper_video("scale", n_frames=25)
    p = synth.write_video(v, tmp_path / "clip.mp4")
    cap = cv2.VideoCapture(str(p))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(5.0)
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    assert len(frames) == 25 and frames[0].shape == (50, 50, 3)
    gray = np.stack([f.mean(axis=2) for f in frames]) / 255
    assert np.abs(gray - v.frames).mean() < 0.03  # lossy, but the same picture
    assert synth.read_truth(p)["n_frames"] == 25


def test_write_refuses_unknown_suffix(tmp_path):
    with pytest.raises(FitodeError, match=".mp4 or .npy"):
        synth.write_video(synth.paper_video("motion", n_frames=3), tmp_path / "clip.avi")


# --- command line --------------------------------------------------------------------------

def test_cli_paper_writes_and_refuses_overwrite(tmp_path, capsys):
    out = tmp_path / "m.npy"
    assert main(["synth", "paper", "motion", "--frames", "20", "--out", str(out)]) == 0
    assert np.load(out).shape == (20, 50, 50)
    assert synth.read_truth(out)["truth"]["g0"] == G0
    capsys.readouterr()
    assert main(["synth", "paper", "motion", "--frames", "20", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "exists" in err and "--force" in err and len(err.splitlines()) == 1
    assert main(["synth", "paper", "scale", "--frames", "7", "--out", str(out), "--force"]) == 0
    assert np.load(out).shape == (7, 50, 50)


def test_cli_equation_and_format(tmp_path):
    out = tmp_path / "osc"
    assert main(["synth", "equation", "--eq", "x'' = -k*x - c*x'", "--const", "k=4", "c=0.1",
                 "--y0", "x=1", "x'=0", "--mode", "intensity", "--frames", "30", "--dt", "0.1",
                 "--size", "32", "--format", "npy", "--out", str(out)]) == 0
    rec = synth.read_truth(tmp_path / "osc.npy")
    assert rec["truth"] == {"k": 4.0, "c": 0.1} and rec["size"] == [32, 32]
    assert rec["settings"]["y0"] == {"x": 1.0, "x'": 0.0}


@pytest.mark.parametrize("argv,match", [
    (["paper", "motion", "--out", "x.avi"], "mp4 or .npy"),
    (["paper", "motion", "--out", "x.mp4", "--format", "npy"], "--format"),
    (["equation", "--eq", "x' = -k*x", "--const", "k", "--y0", "x=1", "--out", "x.npy"], "NAME=VALUE"),
    (["equation", "--eq", "x' = -k*x", "--const", "k=fast", "--y0", "x=1", "--out", "x.npy"], "not a number"),
    (["equation", "--eq", "x' = -k*x +", "--const", "k=1", "--y0", "x=1", "--out", "x.npy"], ""),
    (["scene", "led", "--size", "480", "--out", "x.mp4"], "WIDTHxHEIGHT"),
    (["scene", "nope", "--out", "x.mp4"], "invalid choice"),
    (["paper", "--out", "x.mp4"], "required"),
])
def test_cli_errors_are_one_line_exit_2(tmp_path, monkeypatch, capsys, argv, match):
    monkeypatch.chdir(tmp_path)
    assert main(["synth", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fitode: error:") and len(err.splitlines()) == 1 and match in err
    assert not list(tmp_path.iterdir())
