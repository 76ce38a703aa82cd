"""fitode batch: manifest validation, resuming, failure isolation and the summary, on a stand-in job.

The stand-in `fake_run_video` (used through the batch's `runner` hook, as "test_batch:fake_run_video")
reads a tiny JSON "video" that says what the job does: produce estimates, raise, return NaN, or
kill its worker. The real pipeline on real videos is in test_batch_pipeline.py.
"""
from __future__ import annotations

import importlib.util
import json
import math
import os
import sys
import time
from pathlib import Path

import pytest

from fitode.batch import LocalExecutor, ManifestError, load_manifest, run_batch
from fitode.batch.job import JobOutcome, Task, execute_job
from fitode.batch.summary import SummaryRow, aggregate, rel_error
from fitode.cli import main
from fitode.errors import FitodeError

RUNNER = "test_batch:fake_run_video"
EQ = "I' = -gamma*I"


class _Outcome:
    def __init__(self, report, out_dir):
        self.report, self.out_dir, self.warnings, self.result = report, out_dir, [], None


def fake_run_video(video, out_dir, *, progress=False, log=None, **kwargs):
    """Does what the video file asks; writes result.json like the pipeline."""
    spec = json.loads(Path(video).read_text())
    out_dir = Path(out_dir)
    if out_dir.exists() and any(out_dir.iterdir()):
        raise FitodeError(f"--out {out_dir}: folder exists and is not empty")
    out_dir.mkdir(parents=True, exist_ok=True)
    counter = out_dir.parent / "calls.log"
    with open(counter, "a") as f:  # every call, even a crashing one, leaves a line
        f.write(f"{out_dir.name} {os.getpid()}\n")
    if spec.get("sleep"):
        time.sleep(spec["sleep"])
    if spec.get("crash"):
        os._exit(spec["crash"])
    if spec.get("kill"):  # what the kernel's out-of-memory killer does
        os.kill(os.getpid(), spec["kill"])
    if spec.get("raise"):
        raise FitodeError(spec["raise"])
    if spec.get("bug"):
        raise ZeroDivisionError("a bug")
    seed = kwargs.get("seed", 0)
    value = math.nan if spec.get("nan") else spec["gamma"] + 0.001 * seed + 0.0001 * kwargs.get("max_steps", 0)
    report = {"status": spec.get("status", "complete"),
              "parameters": {"gamma": {"value": None if spec.get("nan") else value, "std": 0.01}},
              "settings": kwargs}
    (out_dir / "result.json").write_text(json.dumps(report))
    return _Outcome(report, out_dir)


def _video(folder: Path, name: str, **spec) -> Path:
    p = folder / name
    p.write_text(json.dumps(spec))
    return p


def _csv(folder: Path, rows: list[str], header: str = "video,setting,eq,true.gamma") -> Path:
    p = folder / "videos.csv"
    p.write_text("\n".join([header, *rows]) + "\n")
    return p


def _calls(out: Path) -> list[str]:
    f = out / "calls.log"
    return [line.split()[0] for line in f.read_text().splitlines()] if f.exists() else []


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


# --- manifest ------------------------------------------------------------------------------

def test_csv_manifest_types_paths_and_precedence(tmp_path):
    (tmp_path / "clips").mkdir()
    _video(tmp_path / "clips", "a b.json", gamma=1)
    _video(tmp_path / "clips", "c.json", gamma=1)
    m = _csv(tmp_path, [
        "# a comment line",
        f"clips/a b.json,led,{EQ},0.8,30,\"10,20,30,40\",16x24,3,\"1,0.2\",2,\"gamma k\",5",
        "clips/c.json,,,,,,,auto,,,,",
    ], header="video,setting,eq,true.gamma,fps,roi,size,stride,prior,const.k,free,restarts")
    # the equation check is another test's business: k and the free names are not in this equation
    man = load_manifest(m, {"eq": EQ, "restarts": 2, "max_steps": 7}, check_equations=False)
    a, c = man.jobs
    assert a.video == (tmp_path / "clips" / "a b.json").resolve()
    assert a.name == "001-a_b" and c.name == "002-c"
    assert a.setting == "led" and c.setting == "default"
    assert a.kwargs == {"eq": EQ, "fps": 30.0, "roi": (10, 20, 30, 40), "size": (24, 16), "stride": 3,
                        "prior": (1.0, 0.2), "free": ("gamma", "k"), "const": {"k": 2.0},
                        "restarts": 5, "max_steps": 7}
    assert a.truth == {"gamma": 0.8} and c.truth == {}
    # the row wins over the command line's defaults; empty cells fall back to them
    assert c.kwargs == {"eq": EQ, "stride": "auto", "restarts": 2, "max_steps": 7}


def test_a_manifest_scale_column_reaches_the_fit(tmp_path):
    _video(tmp_path, "a.json", gamma=1)
    m = _csv(tmp_path, [f"a.json,{EQ},\"10,20,410,20=1.0±0.01\""], header="video,eq,scale")
    job, = load_manifest(m).jobs
    assert job.kwargs["scale"] == "10,20,410,20=1.0±0.01"


def test_toml_manifest_defaults_and_tables(tmp_path):
    _video(tmp_path, "a.json", gamma=1)
    _video(tmp_path, "b.json", gamma=1)
    m = tmp_path / "batch.toml"
    m.write_text(f'''
[defaults]
eq = "{EQ}"
restarts = 2
true = {{ gamma = 0.5 }}

[[job]]
video = "a.json"
setting = "s1"
name = "first"
true.gamma = 0.7
prior = [1.0, 0.2]
color = true

[[job]]
video = "b.json"
seed = 4
''')
    a, b = load_manifest(m, {"restarts": 9}).jobs
    assert (a.name, a.setting, a.truth) == ("first", "s1", {"gamma": 0.7})
    assert a.kwargs == {"eq": EQ, "prior": (1.0, 0.2), "color": True, "restarts": 2}
    assert (b.name, b.truth, b.kwargs["seed"], b.kwargs["restarts"]) == ("002-b", {"gamma": 0.5}, 4, 2)


@pytest.mark.parametrize("header,row,message", [
    ("video,eq,fpss", f"a.json,{EQ},30", "videos.csv line 2, column 'fpss': unknown column (did you mean 'fps'?)"),
    ("video,eq,fps", f"a.json,{EQ},fast", "videos.csv line 2, column 'fps': expected a number, got 'fast'"),
    ("video,eq,fps", f"a.json,{EQ},-3", "videos.csv line 2, column 'fps': must be positive"),
    ("video,eq,restarts", f"a.json,{EQ},1.5", "videos.csv line 2, column 'restarts': expected a whole number"),
    ("video,eq,roi", f"a.json,{EQ},\"1,2,3\"", "videos.csv line 2, column 'roi': expected x,y,w,h"),
    ("video,eq,color", f"a.json,{EQ},maybe", "videos.csv line 2, column 'color': expected true or false"),
    ("video,eq", f"missing.json,{EQ}", "videos.csv line 2, column 'video': no such file: missing.json"),
    ("video,eq,system", f"a.json,{EQ},pendulum", "videos.csv line 2, column 'system': give the equation once"),
    ("video,fps", "a.json,30", "videos.csv line 2, column 'equation': missing"),
    ("video,eq,true", f"a.json,{EQ},1", "column 'true': write one column per constant"),
    ("video,eq,true.2x", f"a.json,{EQ},1", "column 'true.2x': '2x' is not a constant's name"),
    ("video,eq,name", f"a.json,{EQ},../up", "column 'name': '../up' is not a folder name"),
    ("video,eq,name", f"a.json,{EQ},summary.csv", "column 'name': 'summary.csv' is the name of one of the batch's"),
    ("video,eq,start,end", f"a.json,{EQ},3,2", "column 'end': end 2 s is not after start 3 s"),
    ("eq", EQ, "videos.csv line 1: the header has no 'video' column"),
    ("video,eq,scale", f"a.json,{EQ},\"1,2,3=4\"", "column 'scale': --scale: '1,2,3' has 3 numbers"),
])
def test_manifest_errors_name_row_and_column(tmp_path, header, row, message):
    _video(tmp_path, "a.json", gamma=1)
    m = _csv(tmp_path, [row], header=header)
    with pytest.raises(ManifestError) as err:
        load_manifest(m)
    assert message in str(err.value)
    assert "\n" not in str(err.value)


def test_manifest_duplicate_names_and_toml_errors(tmp_path):
    _video(tmp_path, "a.json", gamma=1)
    m = _csv(tmp_path, [f"a.json,{EQ},x", f"a.json,{EQ},x"], header="video,eq,name")
    with pytest.raises(ManifestError, match=r"line 3, column 'name': 'x' is also the name of line 2"):
        load_manifest(m)
    t = tmp_path / "b.toml"
    t.write_text('[[jobs]]\nvideo = "a.json"\n')
    with pytest.raises(ManifestError, match=r"b.toml: unknown table 'jobs'"):
        load_manifest(t)
    t.write_text(f'[defaults]\nvideo = "a.json"\n[[job]]\nvideo = "a.json"\neq = "{EQ}"\n')
    with pytest.raises(ManifestError, match=r"\[defaults\], column 'video': belongs in a job's row"):
        load_manifest(t)
    t.write_text('[[job]]\nvideo = "a.json"\neq = \n')
    with pytest.raises(ManifestError, match=r"b.toml: "):
        load_manifest(t)


def test_settings_hash_covers_fit_settings_but_not_labels(tmp_path):
    v = _video(tmp_path, "a.json", gamma=1)
    m = _csv(tmp_path, [f"a.json,s,{EQ},1"])
    h0 = load_manifest(m).jobs[0].settings_hash
    assert load_manifest(m).jobs[0].settings_hash == h0  # stable
    assert load_manifest(m, {"max_steps": 5}).jobs[0].settings_hash != h0
    _csv(tmp_path, [f"a.json,other-setting,{EQ},2"])
    assert load_manifest(m).jobs[0].settings_hash == h0  # setting and truth do not change the fit
    os.utime(v, ns=(v.stat().st_atime_ns, v.stat().st_mtime_ns + 10**9))
    assert load_manifest(m).jobs[0].settings_hash != h0  # a re-rendered video runs again


# --- running ------------------------------------------------------------------------------

def test_batch_summary_failures_and_resume(tmp_path):
    """Good jobs finish beside a crashing, a raising, a buggy and a NaN job; a re-run after the fix
    runs exactly the fixed ones and leaves the others' folders untouched."""
    _video(tmp_path, "g1.json", gamma=0.5)
    _video(tmp_path, "g2.json", gamma=0.7)
    _video(tmp_path, "crash.json", crash=7)
    _video(tmp_path, "raise.json", **{"raise": "cannot read frame 3"})
    _video(tmp_path, "nan.json", nan=True)
    _video(tmp_path, "bug.json", bug=True)
    m = _csv(tmp_path, [f"g1.json,A,{EQ},0.5", f"crash.json,A,{EQ},0.5", f"g2.json,B,{EQ},0.8",
                        f"raise.json,B,{EQ},", f"nan.json,B,{EQ},", f"bug.json,B,{EQ},"])
    out = tmp_path / "out"
    res = run_batch(m, out, workers=2, runner=RUNNER, log=None, defaults={"max_steps": 10})
    status = {r.name: (r.status, r.error) for r in res.rows}
    assert status["001-g1"] == ("complete", None) and status["003-g2"] == ("complete", None)
    assert status["002-crash"][0] == "failed" and "exited with status 7" in status["002-crash"][1]
    assert status["004-raise"] == ("failed", "cannot read frame 3")
    assert status["005-nan"][0] == "failed" and "NaN" in status["005-nan"][1]
    assert status["006-bug"] == ("failed", "ZeroDivisionError: a bug")
    assert "ZeroDivisionError" in json.loads((out / "006-bug" / "job.json").read_text())["traceback"]
    assert not res.ok and res.counts == {"complete": 2, "incomplete": 0, "failed": 4, "pending": 0}

    # the summary agrees with each job's result.json
    summary = _summary(out)
    for job in summary["jobs"]:
        if job["status"] == "complete":
            report = json.loads((out / job["folder"] / "result.json").read_text())
            assert job["parameters"]["gamma"] == report["parameters"]["gamma"]
    g1 = next(j for j in summary["jobs"] if j["name"] == "001-g1")
    assert g1["rel_error"]["gamma"] == pytest.approx((0.5 + 0.001 - 0.5) / 0.5)
    lines = (out / "summary.csv").read_text().splitlines()
    assert lines[0].split(",")[:4] == ["name", "setting", "video", "status"] and len(lines) == 7
    agg = {a["setting"]: a for a in json.loads((out / "aggregate.json").read_text())["settings"]}
    assert agg["A"]["complete"] == 1 and agg["A"]["failed"] == 1
    assert agg["B"]["parameters"]["gamma"]["mean"] == pytest.approx(0.701)

    # the crashing job ran twice (once in the pool, once alone to be sure it was the culprit)
    calls = _calls(out)
    assert calls.count("002-crash") == 2 and calls.count("001-g1") in (1, 2)
    mtimes = {n: (out / n / "result.json").stat().st_mtime_ns for n in ("001-g1", "003-g2")}

    # same command: nothing changed, so the failed ones run again and fail again; nothing else runs
    (out / "calls.log").unlink()
    run_batch(m, out, workers=2, runner=RUNNER, log=None, defaults={"max_steps": 10}, retry_failed=False)
    assert _calls(out) == []  # --skip-failed: nothing to do
    _video(tmp_path, "crash.json", gamma=0.45)
    _video(tmp_path, "raise.json", gamma=0.6)
    res = run_batch(m, out, workers=2, runner=RUNNER, log=None, defaults={"max_steps": 10})
    assert sorted(_calls(out)) == ["002-crash", "004-raise", "005-nan", "006-bug"]
    assert sorted(res.ran) == ["002-crash", "004-raise", "005-nan", "006-bug"]
    assert sorted(res.reused) == ["001-g1", "003-g2"]
    assert {n: (out / n / "result.json").stat().st_mtime_ns for n in mtimes} == mtimes
    status = {r.name: r.status for r in res.rows}
    assert status == {"001-g1": "complete", "002-crash": "complete", "003-g2": "complete",
                      "004-raise": "complete", "005-nan": "failed", "006-bug": "failed"}
    assert _summary(out)["counts"]["complete"] == 4

    # changed settings (another --max-steps) run everything again; --force too
    (out / "calls.log").unlink()
    run_batch(m, out, workers=2, runner=RUNNER, log=None, defaults={"max_steps": 11})
    assert len(_calls(out)) == 6
    (out / "calls.log").unlink()
    run_batch(m, out, workers=2, runner=RUNNER, log=None, defaults={"max_steps": 11}, force=True)
    assert len(_calls(out)) == 6


def test_incomplete_and_tampered_results_run_again(tmp_path):
    _video(tmp_path, "a.json", gamma=0.5, status="incomplete")
    _video(tmp_path, "b.json", gamma=0.5)
    m = _csv(tmp_path, [f"a.json,A,{EQ},", f"b.json,A,{EQ},"])
    out = tmp_path / "out"
    res = run_batch(m, out, workers=1, runner=RUNNER, log=None)
    assert [r.status for r in res.rows] == ["incomplete", "complete"]
    # a result.json that lost its estimate is not trusted even though job.json says complete
    report = json.loads((out / "002-b" / "result.json").read_text())
    report["parameters"]["gamma"]["value"] = None
    (out / "002-b" / "result.json").write_text(json.dumps(report))
    (out / "calls.log").unlink()
    run_batch(m, out, workers=1, runner=RUNNER, log=None)
    assert sorted(_calls(out)) == ["001-a", "002-b"]


def test_out_dir_must_be_a_batch_folder(tmp_path):
    _video(tmp_path, "a.json", gamma=0.5)
    m = _csv(tmp_path, [f"a.json,A,{EQ},"])
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    with pytest.raises(FitodeError, match="not a fitode batch folder"):
        run_batch(m, other, runner=RUNNER, log=None)
    res = run_batch(m, runner=RUNNER, log=None, workers=1)  # default: beside the manifest
    assert res.out_dir == tmp_path / "videos-results" and (res.out_dir / "001-a" / "result.json").is_file()
    # a second batch on the same folder while one runs is refused
    import fcntl
    with open(res.out_dir / ".lock", "a+") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(FitodeError, match="another fitode batch is writing"):
            run_batch(m, runner=RUNNER, log=None, workers=1)
    assert run_batch(m, runner=RUNNER, log=None, workers=1).reused == ["001-a"]  # released


@pytest.mark.parametrize("where", ["/proc/fitode-batch", "a.json/sub"])
def test_an_unwritable_out_is_one_line_before_any_job(where, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _video(tmp_path, "a.json", gamma=0.5)
    m = _csv(tmp_path, [f"a.json,A,{EQ},"])
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(FitodeError, match=f"--out {where}: cannot write there"):
        run_batch(m, where, runner=RUNNER, log=None, workers=1)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no job ran, nothing was made


class _InterruptAfterOne:
    """An executor whose user presses Ctrl-C after the first job finishes."""

    workers = 1

    def describe(self):
        return "test"

    def run(self, tasks, on_start, on_done):
        on_start(tasks[0])
        on_done(tasks[0], execute_job(tasks[0]))
        on_start(tasks[1])
        raise KeyboardInterrupt


def test_ctrl_c_leaves_a_consistent_summary_and_resumes(tmp_path):
    for i in range(3):
        _video(tmp_path, f"v{i}.json", gamma=0.1 * (i + 1))
    m = _csv(tmp_path, [f"v{i}.json,A,{EQ}," for i in range(3)])
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run_batch(m, out, executor=_InterruptAfterOne(), runner=RUNNER, log=None)
    s = _summary(out)
    assert s["interrupted"] is True
    assert [j["status"] for j in s["jobs"]] == ["complete", "pending", "pending"]
    assert not list(out.glob(".*.tmp"))
    res = run_batch(m, out, workers=2, runner=RUNNER, log=None)
    assert res.reused == ["001-v0"] and sorted(res.ran) == ["002-v1", "003-v2"] and res.ok


def test_bystanders_of_a_worker_death_complete(tmp_path):
    """Two workers: one job's process is killed (as for memory) while another runs; only it fails."""
    _video(tmp_path, "slow.json", gamma=0.5, sleep=1.0)
    _video(tmp_path, "crash.json", kill=9)
    _video(tmp_path, "after.json", gamma=0.6)
    m = _csv(tmp_path, [f"slow.json,A,{EQ},", f"crash.json,A,{EQ},", f"after.json,A,{EQ},"])
    res = run_batch(m, tmp_path / "out", executor=LocalExecutor(2), runner=RUNNER, log=None)
    assert [r.status for r in res.rows] == ["complete", "failed", "complete"]
    assert res.rows[1].error == "the worker was killed by SIGKILL (out of memory?) while running this job"


def test_execute_job_reports_a_missing_runner_as_failed(tmp_path):
    _video(tmp_path, "a.json", gamma=0.5)
    job = load_manifest(_csv(tmp_path, [f"a.json,A,{EQ},"])).jobs[0]
    out = execute_job(Task(job, tmp_path / "o", runner="no_such_module:run"))
    assert isinstance(out, JobOutcome) and out.status == "failed" and "ModuleNotFoundError" in out.error


def test_aggregate_mean_std_and_relative_error():
    rows = [SummaryRow("a", "s", "a", "complete", parameters={"k": {"value": 1.0, "std": 0}}, truth={"k": 2.0}),
            SummaryRow("b", "s", "b", "complete", parameters={"k": {"value": 3.0, "std": 0}}, truth={"k": 2.0}),
            SummaryRow("c", "s", "c", "failed", truth={"k": 2.0}),
            SummaryRow("d", "t", "d", "complete", parameters={"k": {"value": 5.0, "std": 0}})]
    agg = {a["setting"]: a for a in aggregate(rows)}
    k = agg["s"]["parameters"]["k"]
    assert (k["mean"], k["n"], k["true"], k["rel_error"]) == (2.0, 2, 2.0, 0.0)
    assert k["std"] == pytest.approx(math.sqrt(2.0))  # sample std over videos
    assert (agg["s"]["jobs"], agg["s"]["complete"], agg["s"]["failed"]) == (3, 2, 1)
    assert agg["t"]["parameters"]["k"]["std"] == 0.0 and agg["t"]["parameters"]["k"]["true"] is None
    assert rel_error(1.1, -1.0) == pytest.approx(2.1) and rel_error(1.0, 0.0) is None


def test_pooled_interval_is_the_inverse_variance_mean_widened_where_videos_disagree():
    from fitode.batch.summary import Z95, pooled_interval
    # two videos that agree: the interval of one, narrowed by sqrt(2)
    p = pooled_interval([(1.0, [0.9, 1.1]), (1.0, [0.9, 1.1]), (5.0, None)])
    assert p["pooled"] == pytest.approx(1.0) and p["pooled_n"] == 2
    assert p["pooled_high"] - p["pooled"] == pytest.approx(0.1 / math.sqrt(2))
    # the narrower interval weighs more
    assert pooled_interval([(1.0, [0.9, 1.1]), (2.0, [1.0, 3.0])])["pooled"] == pytest.approx((1 * 100 + 2 * 1) / 101)
    # two that disagree (chi2 = 50 for 1 degree of freedom): widened by the Birge ratio, sqrt(50)
    sigma = 0.1 / Z95
    w = pooled_interval([(1.0, [0.9, 1.1]), (1.0 + 10 * sigma, [1.0 + 10 * sigma - 0.1, 1.0 + 10 * sigma + 0.1])])
    assert w["pooled_high"] - w["pooled"] == pytest.approx(0.1 / math.sqrt(2) * math.sqrt(50))
    assert pooled_interval([(1.0, None)]) == {"pooled": None, "pooled_low": None, "pooled_high": None, "pooled_n": 0}


# --- command line -------------------------------------------------------------------------

def test_cli_bad_manifest_is_one_line_status_2(tmp_path, capsys):
    _video(tmp_path, "a.json", gamma=0.5)
    m = _csv(tmp_path, [f"a.json,{EQ},often"], header="video,eq,fps")
    assert main(["batch", str(m)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "videos.csv line 2, column 'fps'" in err
    assert main(["batch", str(tmp_path / "nope.csv")]) == 2
    assert main(["batch", str(m), "--address", "x:1"]) == 2


def test_ray_executor_without_ray_is_a_one_line_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    _video(tmp_path, "a.json", gamma=0.5)
    m = _csv(tmp_path, [f"a.json,A,{EQ},"])
    assert main(["batch", str(m), "--executor", "ray"]) == 2
    assert "--executor ray needs Ray: pip install 'fitode[ray]'" in capsys.readouterr().err


def test_cli_dry_run_lists_jobs_and_writes_nothing(tmp_path, capsys):
    _video(tmp_path, "a.json", gamma=0.5)
    m = _csv(tmp_path, ["a.json,A"], header="video,setting")
    assert main(["batch", str(m), "--eq", EQ, "--max-steps", "5", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "1 job: 0 reused, 1 to run" in out and "would run 001-a" in out and "max_steps=5" in out
    assert not (tmp_path / "videos-results").exists()


@pytest.mark.slow  # a real Ctrl-C to a driver process, and jobs that must be running when it comes
def test_sigint_stops_workers_and_leaves_the_summary_consistent(tmp_path):
    """A real Ctrl-C (SIGINT to the driver) while jobs run: the driver exits promptly, its workers are
    gone, summary.json parses and marks the unfinished jobs pending; the next run finishes them."""
    import signal
    import subprocess
    import sys

    _video(tmp_path, "quick.json", gamma=0.5)
    for i in range(3):
        _video(tmp_path, f"slow{i}.json", gamma=0.5, sleep=30)
    m = _csv(tmp_path, [f"quick.json,A,{EQ},"] + [f"slow{i}.json,A,{EQ}," for i in range(3)])
    out = tmp_path / "out"
    script = ("import sys; from fitode.batch import run_batch\n"
              "if __name__ == '__main__':\n"
              f"    run_batch({str(m)!r}, {str(out)!r}, workers=2, runner={RUNNER!r}, log=None)\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-c", script], env=env, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and len(_calls(out)) < 3:  # quick is done and two slow ones are running
        time.sleep(0.1)
    assert len(_calls(out)) == 3
    t0 = time.time()
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert time.time() - t0 < 15 and proc.returncode != 0 and "KeyboardInterrupt" in err
    worker_pids = [int(line.split()[1]) for line in (out / "calls.log").read_text().splitlines()]
    time.sleep(0.5)
    for pid in worker_pids:  # no worker is left behind, still sleeping
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
    s = _summary(out)
    assert s["interrupted"] is True
    assert [j["status"] for j in s["jobs"]] == ["complete", "pending", "pending", "pending"]
    for i in range(3):
        _video(tmp_path, f"slow{i}.json", gamma=0.5)
    (out / "calls.log").unlink()
    res = run_batch(m, out, workers=2, runner=RUNNER, log=None)
    assert res.ok and res.reused == ["001-quick"] and sorted(_calls(out)) == ["002-slow0", "003-slow1", "004-slow2"]


def test_equations_are_checked_before_anything_runs(tmp_path):
    _video(tmp_path, "a.json", gamma=1)
    _video(tmp_path, "b.json", gamma=1)
    cases = [
        ("video,eq", [f"a.json,{EQ}", "b.json,I' = -gamma*"], "videos.csv line 3, column 'eq': "),
        ("video,eq,true.gama", [f"a.json,{EQ},1"],
         "videos.csv line 2, column 'true.gama': 'gama' is not a learnable constant of the equation (learnable: gamma)"),
        ("video,eq,init.k", [f"a.json,{EQ},1"], "column 'init.k': 'k' is not a learnable constant"),
        ("video,system", ["a.json,no_such_system"], "videos.csv line 2, column 'system': "),
    ]
    for header, rows, message in cases:
        with pytest.raises(ManifestError) as err:
            load_manifest(_csv(tmp_path, rows, header=header))
        assert message in str(err.value) and "\n" not in str(err.value)
    # a shipped system by name, in the auto-detected 'equation' column
    job = load_manifest(_csv(tmp_path, ["a.json,led_decay"], header="video,equation")).jobs[0]
    assert job.kwargs["system"] == "led_decay"


def test_progress_bar_counts_done_failed_running(tmp_path, capsys):
    _video(tmp_path, "ok.json", gamma=0.5)
    _video(tmp_path, "bad.json", **{"raise": "nope"})
    m = _csv(tmp_path, [f"ok.json,A,{EQ},", f"bad.json,A,{EQ},"])
    run_batch(m, tmp_path / "out", workers=1, runner=RUNNER, log=None, progress=True)
    err = capsys.readouterr().err.replace("\r", "\n")
    assert "running=1" in err
    assert "2/2" in err and "done=1, failed=1, running=0" in err


@pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="Ray is not installed")
def test_unreachable_ray_address_fails_fast_and_writes_nothing(tmp_path, capsys):
    _video(tmp_path, "a.json", gamma=0.5)
    m = _csv(tmp_path, [f"a.json,A,{EQ},"])
    t0 = time.time()
    assert main(["batch", str(m), "--executor", "ray", "--address", "127.0.0.1:1"]) == 2
    assert time.time() - t0 < 30
    assert "cannot reach a Ray cluster at 127.0.0.1:1" in capsys.readouterr().err
    assert not (tmp_path / "videos-results").exists()


def test_no_plots_reaches_every_job_and_is_no_new_setting(tmp_path):
    _video(tmp_path, "g1.json", gamma=0.5)
    _video(tmp_path, "g2.json", gamma=0.7)
    m = _csv(tmp_path, [f"g1.json,A,{EQ},0.5", f"g2.json,A,{EQ},0.7"])
    out = tmp_path / "out"
    run_batch(m, out, workers=1, runner=RUNNER, log=None, plots=False)
    for name in ("001-g1", "002-g2"):
        assert json.loads((out / name / "result.json").read_text())["settings"]["plots"] is False
    (out / "calls.log").unlink()
    run_batch(m, out, workers=1, runner=RUNNER, log=None)  # with pictures: the same settings, nothing to run
    assert _calls(out) == []
