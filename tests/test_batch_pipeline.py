"""fitode batch end to end: the real single-video pipeline on tiny generated videos, locally and on Ray.

Each job is an intensity decay I' = -gamma*I (a bright square fading on a dark background,
16x16 pixels, 40 frames), fitted with one restart of 60 steps: seconds per job. These tests
check the batch's bookkeeping, not the estimates' accuracy (bench/ measures that).
"""
from __future__ import annotations

import csv
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")
pytestmark = pytest.mark.slow  # every test fits real videos, and one starts a Ray cluster

from fitode.cli import main  # noqa: E402

EQ = "I' = -gamma*I"
GAMMAS = {"a": 0.4, "b": 0.6, "c": 0.9}
SETTING = {"a": "slow", "b": "slow", "c": "fast"}
TINY = "--restarts 1 --max-steps 60 --window 8 --seed 3".split()


def write_decay_video(path: Path, gamma: float, n: int = 40, fps: float = 10.0, size: int = 16) -> Path:
    """A square whose brightness is exp(-gamma t), written as mp4 with OpenCV."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (size, size))
    assert writer.isOpened()
    rng = np.random.default_rng(int(gamma * 100))
    for k in range(n):
        img = np.full((size, size), 20.0) + rng.normal(0, 1.0, (size, size))
        img[4:12, 4:12] = 40 + 200 * np.exp(-gamma * k / fps)
        writer.write(cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
    writer.release()
    return path


def write_manifest(folder: Path, names: list[str], file: str) -> Path:
    rows = ["video,setting,eq,fps,stride,size,true.gamma"]
    rows += [f"{n}.mp4,{SETTING.get(n, 'broken')},{EQ},10,1,16x16,{GAMMAS.get(n, 1.0)}" for n in names]
    path = folder / file
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="module")
def videos(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("batch-videos")
    for name, gamma in GAMMAS.items():
        write_decay_video(folder / f"{name}.mp4", gamma)
    return folder


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def local_batch(videos, tmp_path_factory):
    """The local batch of three good videos and a corrupt one, run once through the command line."""
    folder = tmp_path_factory.mktemp("batch-local")
    for name in GAMMAS:
        os.link(videos / f"{name}.mp4", folder / f"{name}.mp4")
    (folder / "broken.mp4").write_bytes(b"this is not a video" * 50)
    manifest = write_manifest(folder, ["a", "b", "broken", "c"], "videos.csv")
    out = folder / "out"
    code = main(["batch", str(manifest), "--out", str(out), "--workers", "2", "--quiet", *TINY])
    rows = {r["name"]: r for r in read_csv(out / "summary.csv")}
    return {"folder": folder, "manifest": manifest, "out": out, "code": code, "rows": rows}


def test_local_batch_matches_each_result_and_reruns_only_the_broken_job(local_batch, capsys):
    folder, manifest, out, rows = (local_batch[k] for k in ("folder", "manifest", "out", "rows"))
    assert local_batch["code"] == 1  # a job failed
    assert list(rows) == ["001-a", "002-b", "003-broken", "004-c"]
    assert rows["003-broken"]["status"] == "failed" and rows["003-broken"]["error"]
    assert not (out / "003-broken" / "result.json").exists() or \
        json.loads((out / "003-broken" / "result.json").read_text()).get("status") != "complete"
    for name in ("001-a", "002-b", "004-c"):
        report = json.loads((out / name / "result.json").read_text())
        assert report["status"] == "complete"
        est = report["parameters"]["gamma"]
        row = rows[name]
        assert row["status"] == "complete" and row["error"] == ""
        assert float(row["gamma"]) == est["value"] and float(row["gamma.restart_spread"]) == est["std"]
        # what the job keeps, the batch keeps: the interval, the unit, the verdict and its reason
        assert [float(row["gamma.low"]), float(row["gamma.high"])] == est["interval"]
        assert row["gamma.unit"] == ("latent units" if est["latent_units"] else est["unit"] or "")
        assert (row["gamma.verdict"], row["gamma.reason"]) == (est["verdict"], est["verdict_reason"])
        mine = read_csv(out / name / "estimates.csv")
        kept = [{k: v for k, v in r.items() if k not in ("job", "video", "equation")}
                for r in read_csv(out / "estimates.csv") if r["job"] == name]
        assert kept == mine and mine[0]["interval_low"] and mine[0]["verdict"] and mine[0]["reason"]
        true = GAMMAS[name.split("-")[1]]
        assert float(row["gamma.true"]) == true
        assert float(row["gamma.rel_error"]) == pytest.approx((est["value"] - true) / true)
        assert float(row["wall_s"]) > 0
        assert (row["stride"], float(row["dt"])) == ("1", report["input"]["dt"])
        assert (out / name / "job.json").is_file()
    # the per-setting aggregate is the mean and sample std of the summary's estimates
    agg = {r["setting"]: r for r in read_csv(out / "aggregate.csv")}
    slow = [float(rows[n]["gamma"]) for n in ("001-a", "002-b")]
    assert float(agg["slow"]["gamma.mean"]) == pytest.approx(np.mean(slow))
    assert float(agg["slow"]["gamma.std"]) == pytest.approx(np.std(slow, ddof=1))
    # the pooled interval of the two slow videos: centred between their estimates (pooled_interval's rule
    # is tested on numbers in test_batch)
    assert agg["slow"]["gamma.pooled_n"] == "2" and agg["slow"]["gamma.unit"] == rows["001-a"]["gamma.unit"]
    assert min(slow) <= float(agg["slow"]["gamma.pooled"]) <= max(slow)
    assert float(agg["slow"]["gamma.pooled_low"]) < float(agg["slow"]["gamma.pooled"]) < float(agg["slow"]["gamma.pooled_high"])
    assert agg["fast"]["gamma.n"] == "1" and agg["broken"]["complete"] == "0" and agg["broken"]["failed"] == "1"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"] == {"complete": 3, "incomplete": 0, "failed": 1, "pending": 0}

    # fix the broken video; the same command runs that job only
    mtimes = {n: (out / n / "result.json").stat().st_mtime_ns for n in ("001-a", "002-b", "004-c")}
    write_decay_video(folder / "broken.mp4", 1.0)
    code = main(["batch", str(manifest), "--out", str(out), "--workers", "2", *TINY])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "3 reused, 1 to run" in captured.out and "(1 run now, 3 reused)" in captured.out
    assert {n: (out / n / "result.json").stat().st_mtime_ns for n in mtimes} == mtimes
    rows = {r["name"]: r for r in read_csv(out / "summary.csv")}
    assert all(r["status"] == "complete" for r in rows.values())
    fixed = json.loads((out / "003-broken" / "result.json").read_text())
    assert float(rows["003-broken"]["gamma"]) == fixed["parameters"]["gamma"]["value"]
    # every row carries the verdict its result.json gives
    assert rows["003-broken"]["gamma.verdict"] == fixed["parameters"]["gamma"]["verdict"]
    assert all(r["gamma.verdict"] in ("trusted", "ambiguous", "not trustworthy") for r in rows.values())


ray_missing = importlib.util.find_spec("ray") is None


HEAD = """
import os, sys
os.environ["RAY_AUTH_MODE"] = "disabled"  # a throwaway loopback cluster: its clients hold no token
from fitode.batch.executors import RayExecutor
head = RayExecutor(None, 2)  # what `--executor ray` without --address starts: loopback only
head.start()
import ray
print(ray.get_runtime_context().gcs_address, flush=True)
sys.stdin.read()  # until the test closes stdin
head.stop()
"""


def _descendants(pid: int) -> set[int]:
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        out.add(p)
        todo += children.get(p, [])
    return out


def _listening(pids: set[int]) -> list[str]:
    """Local addresses of the TCP sockets these processes listen on (Linux /proc)."""
    inodes = set()
    for pid in pids:
        for fd in Path(f"/proc/{pid}/fd").glob("*"):
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            f = line.split()
            if f[3] == "0A" and f[9] in inodes:  # 0A: LISTEN
                out.append(f[1])
    return out


def _is_loopback(hex_addr: str) -> bool:
    ip = hex_addr.split(":")[0]
    if len(ip) == 32 and ip.startswith("0000000000000000FFFF0000"):  # ::ffff:a.b.c.d
        ip = ip[24:]
    if len(ip) == 8:  # IPv4, little-endian: 0100007F is 127.0.0.1
        return ip.endswith("7F")
    return ip == "00000000000000000000000001000000"  # ::1


@pytest.mark.skipif(ray_missing, reason="Ray is not installed (pip install 'fitode[ray]')")
def test_ray_executor_gives_the_same_estimates_as_local(local_batch):
    """A local Ray instance (2 CPUs, no dashboard, listening on loopback only) runs the same jobs
    through `--executor ray --address` and gets the same numbers as the local pool did."""
    folder = local_batch["folder"]
    manifest = write_manifest(folder, list(GAMMAS), "good.csv")
    on_ray = folder / "on-ray"
    t0 = time.perf_counter()
    head = subprocess.Popen([sys.executable, "-c", HEAD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    try:
        address = head.stdout.readline().strip()
        assert address.startswith("127.0.0.1:"), address
        started = time.perf_counter() - t0
        listening = _listening(_descendants(head.pid))
        assert listening and all(_is_loopback(a) for a in listening), listening
        proc = subprocess.run([sys.executable, "-m", "fitode", "batch", str(manifest), "--out", str(on_ray),
                               "--executor", "ray", "--address", address, "--quiet", *TINY],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
    finally:
        head.stdin.close()
        head.wait(timeout=60)
    wall = time.perf_counter() - t0
    local = {r["video"]: r for r in local_batch["rows"].values()}
    rows = read_csv(on_ray / "summary.csv")
    assert [r["name"] for r in rows] == ["001-a", "002-b", "003-c"]
    for r in rows:
        assert r["status"] == "complete"
        assert float(r["gamma"]) == pytest.approx(float(local[r["video"]]["gamma"]), rel=1e-9, abs=1e-12)
        assert json.loads((on_ray / r["name"] / "job.json").read_text())["pid"] != os.getpid()
    print(f"ray: instance up in {started:.1f} s, batch of {len(rows)} jobs done {wall:.1f} s after the start")
