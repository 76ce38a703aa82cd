"""The benchmarks (bench/) and `fitode bench`: each runs with --quick, prints its table with finite
numbers and writes its JSON; the command finds, lists and refuses benchmarks in one line."""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from fitode import cli

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"
sys.path.insert(0, str(BENCH))

import common as bc  # noqa: E402
import paper_synthetic  # noqa: E402
import realistic  # noqa: E402
import restarts  # noqa: E402


def _finite(*values) -> bool:
    return all(v is not None and math.isfinite(float(v)) for v in values)


@pytest.mark.slow  # fits in a process pool: seconds even with --quick
def test_paper_synthetic_quick(tmp_path, capsys):
    # two workers: the process pool must be able to re-import the module `fitode bench` loaded
    assert cli.main(["bench", "paper-synthetic", "--quick", "--out", str(tmp_path), "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "g0 mean +- std" in out and "paper g0" in out and "every run" in out
    assert "3.943 +- 0.008" in out  # the paper's motion g0 beside ours
    rec = json.loads((tmp_path / "paper_synthetic.json").read_text())
    assert rec["quick"] is True
    kl = [s for s in rec["summaries"] if s["variant"] == "kl"]
    ablation = [s for s in rec["summaries"] if s["variant"] == "no-kl"]
    assert [s["dataset"] for s in kl] == list(paper_synthetic.DATASETS)
    assert len(ablation) == 3
    for s in rec["summaries"]:
        assert _finite(s["g0"]["mean"], s["g0"]["std"], s["g1"]["mean"], s["g1"]["std"], s["steps_mean"],
                       s["wall_sum_s"])
    runs = rec["runs"]
    assert len(runs) == 3 * 2 + 3 * 1
    # every initialisation of a dataset is its own single-restart fit from its own start
    assert {tuple(sorted(r["init"].items())) for r in runs if r["variant"] == "kl"} == \
        {tuple(sorted(i.items())) for i in rec["settings"]["initialisations"][:2]}
    # the quick limit holds: an encoder trains its 20 steps, a measured path (auto: the motion's
    # angle) is fitted directly in fewer
    assert all(0 < r["steps"] <= 20 and _finite(r["final"]["g0"], r["final"]["g1"], r["wall_s"]) for r in runs)
    assert all(r["history"]["step"][-1] == r["steps"] for r in runs)
    # the report can be printed again from the JSON alone
    assert cli.main(["bench", "paper-synthetic", "--report", str(tmp_path / "paper_synthetic.json")]) == 0
    assert "every run" in capsys.readouterr().out


def test_initialisations_spread_over_the_range():
    inits = paper_synthetic.initialisations(7, seed=0)
    assert len(inits) == 7
    for name in ("g0", "g1"):
        vals = np.array([i[name] for i in inits])
        assert np.all((vals > -10) & (vals < 10))
        # one start in each seventh of [-10, 10]
        assert sorted(np.floor((vals + 10) / (20 / 7)).astype(int).tolist()) == list(range(7))
    assert paper_synthetic.initialisations(7, seed=0) == inits
    assert paper_synthetic.initialisations(7, seed=1) != inits


def test_speed_quick(tmp_path, capsys):
    assert cli.main(["bench", "speed", "--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "per-frame" in out and "per-window" in out and "per-window / per-frame" in out
    rec = json.loads((tmp_path / "speed.json").read_text())
    rows = rec["rows"]
    assert [r["mode"] for r in rows] == ["per-frame", "per-window"]
    for r in rows:
        assert _finite(r["step_min_s"], r["step_median_s"], r["epoch_s"], r["converge_s"], r["peak_rss_mb"])
        assert r["step_min_s"] > 0 and r["converge_steps"] == 8
    pf, pw = rows
    # per-window encodes every window's frames: more frames per step, the same loss at the same weights
    assert pw["frames_encoded_per_step"] == pw["windows"] * 20 > pf["frames_encoded_per_step"] == 40
    assert pw["loss_diff"] < 1e-4
    assert all(_finite(q["step"], q["epoch"], q["converge"], q["peak_rss"]) for q in rec["ratios"])
    (answer,) = rec["answer_rows"]  # one restart to the answer: the quick version stops at its step limit
    assert answer["steps"] == 30 and answer["stop_reason"] == "max_steps" and _finite(answer["wall_s"])
    assert "one restart to the answer" in out and "target" in out and "NOT MET" in out


@pytest.mark.slow  # renders and fits videos: seconds even with --quick
def test_realistic_quick(tmp_path, capsys):
    assert cli.main(["bench", "realistic", "--quick", "--out", str(tmp_path), "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "paper (real data)" in out
    rec = json.loads((tmp_path / "realistic.json").read_text())
    assert [r["scene"] for r in rec["rows"]] == list(realistic.SPEC)
    done = [v for v in rec["videos"] if v["status"] == "complete"]
    assert done  # a failed video is listed under the table, not hidden
    for v in done:
        assert _finite(v["estimate"], v["raw"], v["truth"], v["fit_s"])
    for r in rec["rows"]:
        assert _finite(r["truth"], r["paper"], r["paper_rel_err"])
        if r["n"]:
            assert _finite(r["mean"], r["std"])
    for v in rec["videos"]:
        if v["status"] != "complete":
            assert f"{v['scene']} {v['setting']:g} seed {v['seed']}: {v['status']}" in out


def test_calibration_points_pick_the_extremes_among_kept_frames():
    from fitode.calibrate import parse_calibration
    from fitode.synth import scene

    v = scene("pendulum", 0.45, size=(36, 64), duration=1.0, seed=1)

    class Clip:  # what read_video would say with stride 3
        fps = 60.0
        frame_indices = np.arange(0, 60, 3)

    text = realistic.calibration_points(Clip, v, "theta")
    pts = parse_calibration(text, ["theta"])
    kept = v.latent[Clip.frame_indices, 0]
    assert sorted(p.value for p in pts) == pytest.approx([kept.min(), kept.max()])
    for p in pts:
        assert round(p.time * 60) % 3 == 0


def test_calibration_points_keep_away_from_a_bounce():
    from fitode.calibrate import parse_calibration
    from fitode.synth import scene

    v = scene("bouncing_ball", 9.8, size=(36, 64), seed=2, bounces=2)

    class Clip:
        fps = 60.0
        frame_indices = np.arange(len(v.latent))

    pts = parse_calibration(realistic.calibration_points(Clip, v, "y"), ["y"])
    bounces = [round(t * 60) for t in v.meta["physical"]["bounce_s"]]
    assert len(pts) == 2 and bounces
    for p in pts:  # the lowest point is at a bounce, where the frame does not show the true height
        assert min(abs(round(p.time * 60) - b) for b in bounces) > 2
    assert min(p.value for p in pts) < 0.2 * max(p.value for p in pts)  # still near the floor


def test_needs_calibration_follows_the_analysis():
    from fitode.eqfile import resolve

    assert realistic.needs_calibration(resolve(system="led_decay")[0], "gamma")[0] is False
    assert realistic.needs_calibration(resolve(system="torricelli")[0], "k") == (True, "dependent")
    assert realistic.needs_calibration(resolve(system="pendulum")[0], "L") == (True, "free-small-amplitude")


def test_cmd_bench_lists_and_refuses(tmp_path, capsys, monkeypatch):
    assert cli.main(["bench", "--list"]) == 0
    listed = capsys.readouterr().out
    for name in ("paper-synthetic", "realistic", "speed"):
        assert name in listed
    assert "common" not in listed
    assert cli.main(["bench", "no-such-bench"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no benchmark named 'no-such-bench'" in err[0]
    assert cli.main(["bench", "speed", "--sizes", "12by20"]) == 2
    assert "--sizes" in capsys.readouterr().err
    assert cli.main(["bench", "paper-synthetic", "--datasets", "colour"]) == 2
    assert "unknown colour" in capsys.readouterr().err
    monkeypatch.setenv("FITODE_BENCH_DIR", str(tmp_path))
    assert cli.main(["bench", "speed"]) == 2
    assert "not a fitode bench/ folder" in capsys.readouterr().err


def test_cmd_bench_without_a_checkout(tmp_path, monkeypatch, capsys):
    from fitode import cmd_bench

    monkeypatch.delenv("FITODE_BENCH_DIR", raising=False)
    monkeypatch.setattr(cmd_bench, "candidates", lambda: [tmp_path / "bench"])
    assert cli.main(["bench", "speed"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "source checkout" in err[0]


def test_script_entry_point_errors_in_one_line(capsys):
    # `python bench/realistic.py --scenes volcano`: the same flags as `fitode bench`, a one-line error
    assert bc.script_main(realistic.__doc__, realistic.add_arguments, realistic.run, ["--scenes", "volcano"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "volcano" in err[0]


def test_table_and_finite_helpers():
    text = bc.format_table([{"a": "x", "b": "1.5"}, {"a": "longer", "b": "-"}], [("name", "a"), ("value", "b")])
    lines = text.splitlines()
    assert lines[0].startswith("name") and lines[2].startswith("x ") and lines[2].endswith("1.5")
    assert bc.all_finite([1.0, {"a": [2, 3.5]}]) and not bc.all_finite([{"a": [math.nan]}])
    assert bc.mean_std([1.0, None, 3.0, math.nan]) == (2.0, 1.0, 2)


def test_restarts_summary_takes_medians_and_ratios_to_the_first_count():
    runs = [{"restarts": n, "wall_s": w, "cpu_s": c, "load": 1.0, "values": {"L": 0.25}}
            for n, w, c in ((1, 4.0, 3.0), (8, 9.0, 8.0), (1, 6.0, 5.0), (8, 11.0, 10.0), (1, 100.0, 4.0))]
    rows = restarts.summarise(runs, [1, 8])
    assert [r["wall_s"] for r in rows] == [6.0, 10.0]  # medians: a run slowed by a busy machine does not count
    assert rows[0]["ratio"] == 1.0 and math.isclose(rows[1]["ratio"], 10.0 / 6.0)
    assert math.isclose(rows[1]["cpu_ratio"], 9.0 / 4.0)
    assert "L" in restarts.table(rows)


def test_restarts_refuses_bad_counts_in_one_line(capsys):
    assert cli.main(["bench", "restarts", "--restarts", "1,x"]) == 2
    assert "--restarts" in capsys.readouterr().err


@pytest.mark.slow  # renders and fits videos: seconds even with --quick
def test_coverage_quick(tmp_path, capsys):
    assert cli.main(["bench", "coverage", "--quick", "--out", str(tmp_path), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "95% intervals cover the truth in" in out and "false trust:" in out and "false alarm:" in out
    rec = json.loads((tmp_path / "coverage.json").read_text())
    assert rec["summary"]["clips"] == len(rec["videos"]) == 2


def test_coverage_list_is_fixed_covers_every_case_and_counts_as_defined():
    import coverage
    first, again = coverage.clip_list(list(coverage.CASES), 0), coverage.clip_list(list(coverage.CASES), 0)
    assert first == again and len(first) >= 40
    here = set(coverage.CASES) - set(coverage.missing_cases())
    later = set(coverage.LATER_CASES) & here
    pushed = set(coverage.PUSHED_CASES) & here
    single, pieces = here - set(coverage.PIECES_CASES) - later - pushed, set(coverage.PIECES_CASES) & here
    assert {t["case"] for t in first[: len(single)]} == single  # the earlier list, unchanged, first
    n_single = len(single) * coverage.PER_CASE
    assert {t["case"] for t in first[:n_single]} == single
    assert {t["case"] for t in first[n_single: n_single + len(pieces)]} == pieces
    # the throws come after the pieces, from a stream of their own: the lists before them stay what they were
    n_pieces = len(pieces) * coverage.PER_CASE
    n_later = len(later) * coverage.PER_CASE
    assert "throw" in later and {t["case"] for t in first[n_single + n_pieces: n_single + n_pieces + n_later]} == later
    # and the pushed pucks after those, from a fourth stream
    assert pushed == {"puck"} and {t["case"] for t in first[n_single + n_pieces + n_later:]} == pushed
    for drop in (later | pushed, pushed):
        without = coverage.clip_list([c for c in coverage.CASES if c not in drop], 0)
        assert first[: len(without)] == without
    assert len({t["seed"] for t in first}) == len(first)  # every clip its own draw
    assert "led-linear" in here and any(t["scene_kwargs"].get("curve") == "linear" for t in first if "scene" in t)
    latent = {"truth": 1.0, "estimate": 1.0, "interval": [0.9, 1.1], "verdict": "not trustworthy", "latent_units": True}
    assert not coverage.judge(latent)["covered"] and not coverage.judge(latent)["has_interval"]
    trusted_far = {"truth": 1.0, "estimate": 1.08, "interval": [1.0, 1.16], "verdict": "trusted"}
    right_doubted = {"truth": 1.0, "estimate": 1.01, "interval": [0.99, 1.03], "verdict": "ambiguous"}
    outside_99 = {"truth": 1.0, "estimate": 1.03, "interval": [1.02, 1.04], "verdict": "trusted"}
    assert coverage.judge(trusted_far)["false_trust"] and coverage.judge(trusted_far)["covered"]
    assert coverage.judge(right_doubted)["false_alarm"] and not coverage.judge(right_doubted)["false_trust"]
    assert coverage.judge(outside_99)["false_trust"] and not coverage.judge(outside_99)["covered"]
    s = coverage.summary([trusted_far, right_doubted, outside_99])
    assert (s["covered"], s["false_trust"], s["false_alarm"], s["right"]) == (2, 2, 1, 1)


def test_lightcurve_quick_counts_every_lamp_once(tmp_path, capsys):
    assert cli.main(["bench", "lightcurve", "--quick", "--out", str(tmp_path), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "told wrong" in out and "untold" in out
    rec = json.loads((tmp_path / "lightcurve.json").read_text())
    assert len(rec["lamps"]) == 4 and {r["curve"] for r in rec["lamps"]} == {"srgb", "linear"}
    assert all(r["outcome"] in ("right", "wrong", "untold") for r in rec["lamps"])
    assert all(r["outcome"] == "untold" or r["told"] is not None for r in rec["lamps"])


def test_a_clicked_ruler_is_off_by_about_a_pixel_and_reads_as_a_scale():
    from fitode.scale import END_STD, parse_scale

    ruler = {"p1": [100.0, 20.0], "p2": [300.0, 20.0], "metres": 0.5}
    rng = np.random.default_rng(0)
    sticks = [parse_scale(realistic.clicked_ruler(ruler, rng)) for _ in range(400)]
    ends = np.array([[*s.p1, *s.p2] for s in sticks]) - [100.0, 20.0, 300.0, 20.0]
    assert np.std(ends, axis=0) == pytest.approx([END_STD] * 4, rel=0.15)  # each end clicked, each axis
    assert all(s.distance == 0.5 and s.end_std == END_STD for s in sticks)  # the error the tool assumes


def test_speed_clip_counts_each_import_once_and_by_its_own_package():
    import speed_clip
    log = "\n".join([
        "import time: self [us] | cumulative | imported package",
        "import time:        10 |        100 |   torch._C",  # nested: in torch's cumulative
        "import time:        20 |        110 | torch",
        "import time:        45 |         45 |   sympy",  # fitode.eqfile's import of sympy
        "import time:         5 |         50 | fitode.eqfile",
        "not an import line",
    ])
    got = speed_clip.imports(log, top=2)
    assert math.isclose(got["total"], 160e-6)
    assert list(got["biggest"]) == ["sympy", "torch"]
    assert math.isclose(got["biggest"]["torch"], 30e-6) and math.isclose(got["biggest"]["sympy"], 45e-6)


def _noting(calls: list):
    """A stand-in for the driver's timer: each call of a patched function notes its stage."""
    def timed(stage, fn):
        def wrapper(*a):
            calls.append(stage)
            return fn(*a)
        return wrapper
    return timed


def test_speed_clip_times_a_stage_from_the_import_that_loads_it(tmp_path, monkeypatch):
    # the driver patches a stage's function when the command imports its module, so that
    # nothing the module imports moves into the start-up
    import speed_clip
    (tmp_path / "late_stage_mod.py").write_text("def work(x):\n    return 2 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    calls = []
    timed = _noting(calls)
    hook = speed_clip._PatchOnImport({"late_stage_mod": [("fit", "work")]}, timed)
    monkeypatch.setattr(sys, "meta_path", [hook, *sys.meta_path])
    assert "late_stage_mod" not in sys.modules
    import late_stage_mod
    try:
        assert late_stage_mod.work(3) == 6 and calls == ["fit"]
    finally:
        sys.modules.pop("late_stage_mod", None)


def test_speed_clip_times_a_method_named_by_its_class(tmp_path, monkeypatch):
    # the tracking is timed at TrackRecorder.finish, a method: the patch finds it on its class
    import speed_clip
    (tmp_path / "late_class_mod.py").write_text(
        "class Recorder:\n    def finish(self, x):\n        return x + 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    calls = []
    timed = _noting(calls)
    hook = speed_clip._PatchOnImport({"late_class_mod": [("of which tracking", "Recorder.finish"),
                                                         ("fit", "Missing.method")]}, timed)
    monkeypatch.setattr(sys, "meta_path", [hook, *sys.meta_path])
    import late_class_mod
    try:
        assert late_class_mod.Recorder().finish(1) == 2 and calls == ["of which tracking"]
    finally:
        sys.modules.pop("late_class_mod", None)
    assert "of which tracking" in speed_clip.PARTS
