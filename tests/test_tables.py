"""estimates.csv and track.csv: the run's numbers as result.json has them, in tables to take away."""
from __future__ import annotations

import csv
import io
import json
import math

import pytest

from fitode.examples.make_example import decay_values, render_glow, write_mp4
from fitode.pipeline import run_job
from fitode.tables import ESTIMATE_COLUMNS, estimates_csv, track_csv, track_header, write_run_tables


def _report() -> dict:
    return {
        "input": {"fps": 30.0, "stride": 2, "first_frame_time_s": 1.0},
        "parameters": {
            "L": {"value": 0.25073, "std": 0.001, "unit": "m", "calibrated": False, "verdict": "trusted",
                  "verdict_reason": "the restarts agree"},
            "k": {"value": 1.5, "std": math.nan, "unit": None, "calibrated": True, "verdict": "ambiguous",
                  "verdict_reason": "one run", "interval": [1.2, 1.8]},
        },
        "trajectory": {"time": [1.0, 1.0 + 1 / 15, 1.0 + 2 / 15], "states": ["x", "y"],
                       "latent": [[0.1, 1.0], [0.2, 2.0], [0.3, None]],
                       "rollout": [[0.1, 1.5], [0.25, 2.0], [0.5, 3.0]]},
    }


def _rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


def test_estimates_columns_and_values():
    rows = _rows(estimates_csv(_report()))
    assert tuple(rows[0]) == ESTIMATE_COLUMNS
    L, k = rows
    assert (L["constant"], float(L["value"]), float(L["restart_spread"]), L["unit"], L["calibrated"], L["verdict"],
            L["reason"]) == ("L", 0.25073, 0.001, "m", "False", "trusted", "the restarts agree")
    assert L["interval_low"] == L["interval_high"] == ""
    assert (float(k["interval_low"]), float(k["interval_high"]), k["calibrated"]) == (1.2, 1.8, "True")


def test_track_columns_frames_and_residuals():
    rows = _rows(track_csv(_report()))
    assert list(rows[0]) == track_header(["x", "y"]) == ["time_s", "frame", "x", "y", "x_fit", "y_fit",
                                                          "x_residual", "y_residual"]
    assert [int(r["frame"]) for r in rows] == [30, 32, 34]  # 1 s at 30 fps, every 2nd frame
    assert float(rows[1]["x_residual"]) == pytest.approx(0.2 - 0.25)
    assert rows[2]["y"] == "" and rows[2]["y_residual"] == ""  # a null in result.json stays empty
    assert track_csv({"parameters": {}, "trajectory": None}) is None


def test_nan_is_written_empty(tmp_path):
    assert write_run_tables(_report(), tmp_path) == ["estimates.csv", "track.csv"]
    k = _rows((tmp_path / "estimates.csv").read_text())[1]
    assert k["restart_spread"] == ""


@pytest.mark.slow  # a tiny fit, about 3 s
def test_a_run_folder_holds_both_tables_equal_to_result_json(tmp_path):
    video = write_mp4(tmp_path / "glow.mp4", render_glow(decay_values(30, 10.0, 0.5), size=16), 10.0)
    lines: list[str] = []
    # cos(a): a constant where a state is expected; the parser's hint is printed and kept (tests/test_eqparse.py)
    out = run_job(video, tmp_path / "run", eq="I' = -gamma*I*cos(a)", start=0.5, restarts=1, max_steps=5,
                  window=8, stride=1, log=lines.append)
    report = json.loads((out.out_dir / "result.json").read_text())
    assert {"estimates.csv", "track.csv"} <= set(report["files"])
    hint = "'a' inside cos(...) is a constant to learn, not a state; if you meant the state I, write cos(I)"
    assert f"hint: {hint}" in lines and hint in report["warnings"]
    est = _rows((out.out_dir / "estimates.csv").read_text())
    assert [e["constant"] for e in est] == list(report["parameters"]) == ["gamma", "a"]
    for e in est:
        p = report["parameters"][e["constant"]]
        assert float(e["value"]) == p["value"]
        assert e["restart_spread"] == ("" if p["std"] is None else repr(p["std"]))  # null in result.json: an empty cell
        assert (e["verdict"], e["reason"], e["calibrated"]) == (p["verdict"], p["verdict_reason"], str(p["calibrated"]))
    track = _rows((out.out_dir / "track.csv").read_text())
    traj = report["trajectory"]
    assert len(track) == len(traj["time"]) == report["input"]["frames_used"]
    assert [float(r["time_s"]) for r in track] == traj["time"]
    assert [float(r["I"]) for r in track] == [z[0] for z in traj["latent"]]
    assert [float(r["I_fit"]) for r in track] == [z[0] for z in traj["rollout"]]
    assert int(track[0]["frame"]) == 5  # --start 0.5 at 10 fps


def test_track_columns_say_a_measured_states_unit_apart_from_the_image_pixels():
    from fitode.tables import track_header
    header = track_header(["y"], ["track"], {"y": "px"})
    assert header == ["time_s", "frame", "y [px]", "y_fit [px]", "y_residual [px]", "x_px", "y_px"]
    assert len(set(header)) == len(header)
    assert track_header(["y"], (), None)[2:] == ["y", "y_fit", "y_residual"]
