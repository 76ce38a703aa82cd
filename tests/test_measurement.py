"""What was measured, drawn on the frames: the measurement record in source pixels (fitode.measurement),
track.png, and plots labelled in the estimate's units."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from fitode.eqparse import parse
from fitode.examples.make_example import decay_values, render_glow, write_mp4
from fitode.measurement import geometry, in_source_pixels, readings
from fitode.pipeline import ReadOptions, read_clip, run_job

SOURCE = (240, 320)  # (H, W) of the generated source frames
ROI = (24, 12, 280, 216)  # x, y, w, h: read at 64 pixels on the short side, 3.4 source pixels per frame pixel


def disc_clip(path: Path, centres: np.ndarray, radii: np.ndarray, seed: int = 0) -> Path:
    """A dark disc on a light, noisy, textured wall at the given sub-pixel centres and radii, as a .npy source."""
    rng = np.random.default_rng(seed)
    wall = 190 + 20 * cv2.GaussianBlur(rng.standard_normal(SOURCE), (0, 0), 6)
    frames = []
    for (x, y), r in zip(centres, radii):
        ys, xs = np.mgrid[:SOURCE[0], :SOURCE[1]]
        cover = np.clip(r + 0.5 - np.hypot(xs - x, ys - y), 0, 1)  # anti-aliased edge
        img = wall * (1 - cover) + 40 * cover + rng.normal(0, 2, SOURCE)
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
    np.save(path, np.stack(frames))
    return path


def measured(path: Path, model, equation: str, **read):
    clip, _ = read_clip(path, ReadOptions(fps=30.0, stride=1, **read))
    model.bind(parse(equation))
    prepared = model.prepare(torch.as_tensor(clip.frames), "linear")
    return clip, prepared, in_source_pixels(prepared.drawing, geometry(clip))


def test_a_position_is_recorded_in_source_pixels_through_the_crop_and_the_resize(tmp_path):
    from fitode.train.observe import PositionObservation
    t = np.arange(60) / 30.0
    centres = np.stack([70 + 40 * t ** 2, 50 + 25 * t ** 2], axis=1)  # accelerating along a known line, inside the crop
    path = disc_clip(tmp_path / "slide.npy", centres, np.full(len(t), 9.0))
    clip, prepared, m = measured(path, PositionObservation(), "s'' = a", roi=ROI)  # s says no axis: the line
    assert clip.size != SOURCE and geometry(clip).scale[0] > 3  # measured on shrunk frames
    assert prepared.drawing["space"] == "frames" and m["space"] == "source"
    track = np.array(m["track"])
    error = np.hypot(*(track - centres).T)
    assert error.max() < 1.5 and np.median(error) < 0.8, error  # within a pixel or so of the truth
    d = np.array(m["line"]["direction"])
    truth = np.array([40.0, 25.0]) / np.hypot(40, 25)
    assert abs(abs(d @ truth) - 1) < 1e-3
    assert m["states"] == {"s": "line"} and m["crop"] == list(geometry(clip).box)
    assert m["source_size"] == [SOURCE[1], SOURCE[0]]
    # the fitted trajectory drawn on the image: a latent affine in the path maps back onto it
    z = (track - track.mean(axis=0)) @ d * -0.37 + 2.0
    (reading,) = readings(m, z[:, None], z[:, None], ["s"])
    assert np.abs(reading.points - centres).max() < 1.5


def test_a_state_read_along_an_image_axis_is_drawn_over_time_in_its_pixels():
    # y'' = -g reads y up the image: track.png's panel over time shows that height, and the fitted
    # trajectory lands on the tracked point's column (it had no panel, so a ball's flights went unseen)
    t = np.arange(40) / 30.0
    track = np.stack([300 + 5 * t, 400 - 200 * t + 490 * t ** 2], axis=1)  # image rows grow down
    m = {"states": {"y": "y"}, "track": track.tolist(), "space": "source"}
    z = (-track[:, 1] - 12.0) * 0.01  # the latent: affine in the height
    (reading,) = readings(m, z[:, None], z[:, None], ["y"])
    np.testing.assert_allclose(reading.measured, -track[:, 1])
    np.testing.assert_allclose(reading.fitted, -track[:, 1], atol=1e-9)
    np.testing.assert_allclose(reading.points, track, atol=1e-9)
    assert "up" in reading.label


def test_the_trajectory_drawn_is_mapped_over_the_frames_read_and_not_over_those_set_aside():
    # a block that slides out of a --roi: the frames after it left hold what the reader found
    # instead (listed as mended, read from their neighbours in the latent), which pulled the map
    # from the latent to the reading, and the fitted trajectory was drawn 15 px off the path
    t = np.arange(60) / 60.0
    along = 40 + 300 * t ** 2
    track = np.stack([100 + 0.8 * along, 80 + 0.6 * along], axis=1)
    z = (along - 100.0) * 0.003  # the latent: affine in the distance along the line
    track[45:] = [[135.0, 100.0]] * 15  # gone: something else found where it started
    z[45:] = z[44]
    m = {"states": {"s": "line"}, "track": track.tolist(), "space": "source", "mended": list(range(45, 60)),
         "line": {"point": [100.0, 80.0], "direction": [0.8, 0.6]}}
    (reading,) = readings(m, z[:, None], z[:, None], ["s"])
    np.testing.assert_allclose(reading.fitted[:45], along[:45], atol=1e-6)


def test_a_size_is_recorded_with_its_radii_in_source_pixels(tmp_path):
    from fitode.train.observe import SizeObservation
    radii = np.linspace(10, 40, 50)
    centres = np.tile([[150.0, 118.0]], (50, 1))
    path = disc_clip(tmp_path / "grow.npy", centres, radii)
    _, _, m = measured(path, SizeObservation(), "r' = k*r")
    got = np.array(m["radii"])
    assert np.median(np.abs(got[2:-2] - radii[2:-2])) < 1.5, got - radii
    assert np.hypot(*(np.array(m["track"])[5] - centres[5])) < 1.5
    x0, y0, x1, y1 = m["region"]
    assert x0 < 150 - 38 and x1 > 150 + 38 and y0 < 118 - 38 and y1 > 118 + 38


def test_a_free_latent_records_only_where_the_frames_change():
    from fitode.train.observe import ObservationModel
    frames = torch.zeros(20, 1, 16, 16)
    frames[:, 0, 4:8, 10:14] = torch.linspace(0, 1, 20)[:, None, None]
    model = ObservationModel()
    model.bind(parse("x'' = -w*x"))
    d = model.prepare(frames).drawing
    assert d["kind"] == "any" and "track" not in d
    assert d["region"] == [9.5, 3.5, 13.5, 7.5]


def test_track_png_says_when_there_is_no_place_to_draw(tmp_path, monkeypatch):
    from fitode import plots
    titles = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: titles.append(fig._suptitle.get_text()) or Path(path))
    img = np.zeros((16, 16, 3))
    plots.plot_track(tmp_path / "t.png", {"kind": "any", "region": [2, 2, 9, 9]}, {0: (img, (-0.5, 15.5, 15.5, -0.5))},
                     np.arange(3) * 0.1)
    assert "no point, line or angle to draw" in titles[0]


@pytest.fixture(scope="module")
def glow(tmp_path_factory) -> Path:
    return write_mp4(tmp_path_factory.mktemp("glow") / "glow.mp4", render_glow(decay_values(40, 10.0, 0.5), size=16), 10.0)


def test_a_calibrated_run_writes_track_png_and_labels_its_plots_in_physical_units(glow, tmp_path, monkeypatch):
    from fitode import plots
    labels: dict[str, list[str]] = {}
    save = plots._save

    def keep(fig, path):
        labels[Path(path).name] = [ax.get_ylabel() for ax in fig.axes]
        return save(fig, path)
    monkeypatch.setattr(plots, "_save", keep)
    # a trained encoder (observe any), so that params.png, drawn only after training, is there
    out = run_job(glow, tmp_path / "c", eq="I' = -gamma*I + c", calibrate="I(0)=1; I(3.5)=0.3", log=None,
                  restarts=2, max_steps=10, window=8, stride=1, observe="any")
    assert "track.png" in out.report["files"] and (out.out_dir / "track.png").stat().st_size > 1000
    assert out.report["measurement"]["kind"] == json.loads((out.out_dir / "result.json").read_text())["measurement"]["kind"]
    assert all("calibrated" in label for label in labels["latent.png"])
    cal = out.report["parameters"]["c"]
    assert cal["calibrated"]
    c_label = [label for label in labels["params.png"] if label.startswith("c")]
    assert c_label and "calibrated" in c_label[0]
    g_label = [label for label in labels["params.png"] if label.startswith("gamma")]
    assert g_label and "latent" not in g_label[0]  # a rate is the same in every unit


def test_track_csv_carries_the_measured_point_in_source_pixels():
    from fitode.tables import track_csv
    report = {"input": {"fps": 10.0, "stride": 1, "first_frame_time_s": 0.0},
              "trajectory": {"states": ["x"], "time": [0.0, 0.1, 0.2], "latent": [[0.0], [1.0], [2.0]],
                             "rollout": [[0.0], [1.0], [2.5]]},
              "measurement": {"kind": "position", "track": [[10.5, 20.0], None, [12.25, 22.0]], "radii": [3.0, 4.0]}}
    lines = track_csv(report).strip().split("\n")
    assert lines[0].endswith("x_residual,x_px,y_px")  # radii of another length are not a column
    assert lines[1].endswith(",10.5,20.0") and lines[2].endswith(",,") and lines[3].endswith(",12.25,22.0")


def test_an_angle_record_is_read_in_degrees_and_drawn_about_its_pivot(tmp_path):
    """The angle observation's record (pivot, radius, a track on the circle) as the tracking model writes it."""
    from types import SimpleNamespace

    from fitode import plots
    from fitode.train.observe.angle import angles
    from fitode.train.observe.circle import fit_circle
    theta = 0.3 * np.cos(np.linspace(0, 12, 80))  # radians, from the direction it hangs in
    pivot, radius, hang = np.array([120.0, -40.0]), 150.0, np.pi / 2 + 0.05  # hangs a little off straight down
    track = pivot + radius * np.stack([np.cos(hang + theta), np.sin(hang + theta)], axis=1)
    # the observation reads this track as theta, sign and zero: the picture must read it the same
    read, hung = angles(track, fit_circle(track))
    assert np.allclose(read, theta, atol=2e-3) and hung == pytest.approx(hang, abs=2e-3)  # its hang: from the turns
    m = {"kind": "angle", "space": "source", "states": {"theta": "angle"}, "pivot": list(pivot), "radius": radius,
         "hanging": hang, "track": track.tolist(), "source_size": [240, 160], "crop": [0, 0, 240, 160]}
    (reading,) = readings(m, theta[:, None], theta[:, None], ["theta"])
    assert np.allclose(reading.measured, np.degrees(theta)) and np.allclose(reading.fitted, np.degrees(theta))
    assert np.abs(reading.points - track).max() < 1e-6
    assert reading.measured[0] > 0 and track[0, 0] < pivot[0] + radius * np.cos(hang)  # positive: clockwise, left
    img = np.zeros((160, 240, 3))
    path = plots.plot_track(tmp_path / "track.png", m, {0: (img, (-0.5, 239.5, 159.5, -0.5))}, np.arange(80) * 0.05,
                            readings=[reading])
    assert path.stat().st_size > 1000
    result = SimpleNamespace(states=["theta"], meta={"measurement": m, "physical_units": True, "measured": True})
    assert plots.state_labels(result) == ["theta (radians)"] and plots.angle_states(result) == ["theta"]
