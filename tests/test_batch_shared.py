"""What the batch shares with the rest of fitode: JSON that always parses, written atomically
(fitode.jsonio), and a worker pool that Ctrl-C stops at once (fitode.batch.pool)."""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numpy as np
import pytest

from fitode.batch.pool import WorkerPool, worker_context
from fitode.jsonio import dumps, to_jsonable, write_json, write_text


def test_non_finite_numbers_become_null_and_numpy_becomes_python():
    obj = {"x": math.inf, "y": [np.float32(2.0), np.int64(3), np.bool_(True)], "z": np.array([[1.0, np.nan]]),
           "t": (1, -math.inf), 4: Path("a/b"), np.int64(5): "five"}
    want = {"x": None, "y": [2.0, 3, True], "z": [[1.0, None]], "t": [1, None], "4": "a/b", "5": "five"}
    assert to_jsonable(obj) == want
    assert json.loads(dumps(obj)) == want  # what is read back is what to_jsonable said


def test_dumps_keeps_the_layout_of_json_dumps():
    obj = {"a": [1, 2.5], "b": {"c": None}}
    assert dumps(obj) == json.dumps(obj, indent=1)
    assert dumps(obj, indent=None) == json.dumps(obj)


def test_write_json_replaces_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "r.json"
    path.write_text("old")
    assert write_json({"v": math.nan}, path) == path
    assert json.loads(path.read_text()) == {"v": None}
    write_text("x,y\n", tmp_path / "t.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "t.csv"]


def test_a_failed_write_keeps_the_old_file(tmp_path):
    path = tmp_path / "r.json"
    write_json({"v": 1}, path)
    with pytest.raises(TypeError):
        write_json({"v": object()}, path)  # JSON has no type for it: nothing is written
    assert json.loads(path.read_text()) == {"v": 1} and [p.name for p in tmp_path.iterdir()] == ["r.json"]
    assert json.loads(dumps({"v": object()}, default=lambda o: "obj")) == {"v": "obj"}


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a killed worker the pool has not reaped yet is a zombie: gone for our purpose
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return True


def test_an_interrupt_stops_the_workers_at_once():
    # spawn: nothing is preloaded, and time.sleep and os.getpid need no import of fitode
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        with WorkerPool(1, worker_context("spawn"), initializer=time.sleep, initargs=(0,)) as pool:
            pid = pool.submit(os.getpid).result()
            running = pool.submit(time.sleep, 60)
            while not running.running():
                time.sleep(0.01)
            time.sleep(0.2)  # into the sleep
            raise KeyboardInterrupt
    assert time.perf_counter() - t0 < 30 and not _alive(pid)
