"""What runs inside a worker: one job, from its video to its own output folder.

Nothing here imports torch at module level: a worker must be able to set its thread count
before torch starts its thread pools.
"""
from __future__ import annotations

import importlib
import math
import os
import shutil
import socket
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .manifest import Job

DEFAULT_RUNNER = "fitode.pipeline:run_job"


@dataclass
class Task:
    """A job and where it writes. runner: "module:function" with run_job's signature (tests swap it)."""

    job: Job
    out_dir: Path
    runner: str = DEFAULT_RUNNER
    attempt: int = 1
    plots: bool = True  # the job's pictures (a choice of output, outside the settings hash: same numbers)


@dataclass
class JobOutcome:
    """What a worker reports back: small (no arrays), so it crosses process and node boundaries cheaply.

    status: "complete" | "incomplete" (the fit stopped early, e.g. interrupted) | "failed".
    parameters: name -> {"value", "std", "interval", "verdict", "verdict_reason", "unit", "calibrated",
        "latent_units"} as in result.json (where it has them).
    """

    name: str
    status: str
    error: str | None = None
    wall_s: float = 0.0
    parameters: dict[str, dict[str, float | None]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    traceback: str | None = None
    host: str = ""
    pid: int = 0


def single_thread() -> None:
    """One job per core: torch's and OpenCV's own thread pools would only fight each other."""
    os.environ["OMP_NUM_THREADS"] = "1"
    os.environ["MKL_NUM_THREADS"] = "1"
    import torch

    torch.set_num_threads(1)
    try:
        torch.set_num_interop_threads(1)
    except RuntimeError:  # only settable before the first parallel op; harmless when too late
        pass
    try:
        import cv2

        cv2.setNumThreads(1)
    except ImportError:
        pass


def load_runner(spec: str) -> Callable[..., Any]:
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name or "run_job")


def execute_job(task: Task) -> JobOutcome:
    """Run one job. Every error becomes a failed outcome: a batch never stops for one video."""
    from fitode.errors import FitodeError

    job = task.job
    t0 = time.perf_counter()
    c0 = time.process_time()
    base = dict(name=job.name, host=socket.gethostname(), pid=os.getpid())
    try:
        # the driver hands out only jobs to (re)run, in folders it owns: what a failed or killed
        # attempt left there goes, since the pipeline refuses to write into a non-empty folder
        if Path(task.out_dir).exists():
            shutil.rmtree(task.out_dir)
        run = load_runner(task.runner)
        outcome = run(job.video, task.out_dir, progress=False, log=None, plots=task.plots, **job.kwargs)
        report = getattr(outcome, "report", None)
        if report is None:
            report = read_report(Path(task.out_dir))
        status, problem = check_report(report)
        # CPU seconds say what a job costs whatever else the machine is doing; wall time does not
        details = {**report_details(report), "cpu_s": round(time.process_time() - c0, 3)}
        return JobOutcome(status=status, error=problem, wall_s=time.perf_counter() - t0,
                          parameters=report_parameters(report), warnings=list(getattr(outcome, "warnings", []) or []),
                          details=details, **base)
    except FitodeError as exc:
        return JobOutcome(status="failed", error=one_line(str(exc)), wall_s=time.perf_counter() - t0, **base)
    except MemoryError:
        return JobOutcome(status="failed", error="out of memory", wall_s=time.perf_counter() - t0, **base)
    except Exception as exc:  # a bug or an unreadable file: keep the traceback for the job's job.json
        return JobOutcome(status="failed", error=one_line(f"{type(exc).__name__}: {exc}"),
                          wall_s=time.perf_counter() - t0, traceback=traceback.format_exc(), **base)


def one_line(text: str, limit: int = 400) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_report(out_dir: Path) -> dict[str, Any]:
    import json

    return json.loads((out_dir / "result.json").read_text())


def report_parameters(report: dict[str, Any]) -> dict[str, dict[str, float | None]]:
    out = {}
    for name, est in (report.get("parameters") or {}).items():
        est = est if isinstance(est, dict) else {}
        out[name] = {"value": _num(est.get("value")), "std": _num(est.get("std"))}
        out[name].update({k: est[k] for k in ("verdict", "verdict_reason", "unit") if isinstance(est.get(k), str)})
        for flag in ("calibrated", "latent_units"):
            if isinstance(est.get(flag), bool):
                out[name][flag] = est[flag]
        interval = est.get("interval")
        if isinstance(interval, list) and len(interval) == 2 and all(_num(v) is not None for v in interval):
            out[name]["interval"] = [float(interval[0]), float(interval[1])]
    return out


def report_details(report: dict[str, Any]) -> dict[str, Any]:
    """A few facts worth a summary column (the stride `auto` chose, dt, the equation fitted and,
    of several candidates, the one preferred), where the report has them."""
    out: dict[str, Any] = {}
    source = report.get("input") if isinstance(report.get("input"), dict) else report
    for key in ("fps", "stride", "dt", "frames_used"):
        v = source.get(key)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            out[key] = v
    equation = report.get("equation")
    if isinstance(equation, dict) and isinstance(equation.get("text"), str):
        out["equation"] = equation["text"]  # of several candidates, the one reported (fitode.compare)
    comparison = report.get("comparison")
    if isinstance(comparison, dict):
        out["preferred"] = comparison.get("preferred")
    runs = report.get("runs")
    if isinstance(runs, list):
        out["runs"] = len(runs)
        out["failed_runs"] = sum(1 for r in runs if isinstance(r, dict) and r.get("status") not in ("ok", None))
    return out


def check_report(report: Any) -> tuple[str, str | None]:
    """(status, problem): "complete" only when every estimate is a finite number."""
    if not isinstance(report, dict):
        return "failed", "result.json is not a JSON object"
    params = report.get("parameters")
    if not isinstance(params, dict) or not params:
        return "failed", "result.json has no parameters"
    bad = [n for n, e in params.items() if _num(e.get("value") if isinstance(e, dict) else None) is None]
    if bad:
        return "failed", f"no finite estimate of {', '.join(bad)} (NaN)"
    status = report.get("status", "complete")
    if status != "complete":
        return "incomplete", one_line(str(report.get("reason") or f"the fit ended {status}"))
    return "complete", None


def _num(v: Any) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v) if math.isfinite(v) else None
