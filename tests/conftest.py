"""The suite runs in parallel (pytest-xdist; `-n auto` in pyproject.toml's addopts): one worker per
core this process may use, at most MAX_WORKERS, each with one thread for torch and BLAS. These
models and matrices are small: two workers on two cores that each start a second thread wait on
each other (train/threads.py), and a container's cpu_count can name cores it may not use."""
from __future__ import annotations

import os

MAX_WORKERS = 8  # each worker holds torch and its clips (a few hundred MB)

if os.environ.get("PYTEST_XDIST_WORKER"):
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(name, "1")


def pytest_xdist_auto_num_workers(config) -> int:
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, MAX_WORKERS))
