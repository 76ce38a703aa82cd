"""The batch driver: plan (what to reuse, what to run), run on an executor, keep the summary current.

The batch's out dir holds `batch.json` (which manifest it belongs to), one folder per job (what
`run_video` writes, plus the batch's `job.json`: the settings hash, status, error and wall time),
and the summary files. A job is reused when its job.json says complete with the same settings
hash and its result.json is valid with a finite estimate of every constant; anything else runs
again, into a cleared folder.
"""
from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Mapping

from fitode.errors import FitodeError
from fitode.jsonio import write_json

from .executors import Executor, make_executor
from .job import DEFAULT_RUNNER, JobOutcome, Task, check_report, report_details, report_parameters
from .manifest import Job, Manifest, load_manifest
from .summary import SummaryRow, aggregate, counts, write_summary

MARKER = "batch.json"
LOCK = ".lock"
JOB_FILE = "job.json"


@dataclass
class BatchResult:
    """What `run_batch` returns: the summary rows (manifest order), the per-setting aggregate and where it all is."""

    out_dir: Path
    rows: list[SummaryRow]
    aggregate: list[dict[str, Any]]
    ran: list[str] = field(default_factory=list)
    reused: list[str] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def counts(self) -> dict[str, int]:
        return counts(self.rows)

    @property
    def ok(self) -> bool:
        return all(r.status == "complete" for r in self.rows)


def default_out_dir(manifest: Path) -> Path:
    """Beside the manifest, so re-running the same command from anywhere resumes the same batch."""
    return manifest.parent / f"{manifest.stem}-results"


def run_batch(manifest: str | Path | Manifest, out: str | Path | None = None, *, executor: str | Executor = "local",
              workers: int | None = None, address: str | None = None, force: bool = False,
              retry_failed: bool = True, defaults: Mapping[str, Any] | None = None, progress: bool = False,
              log: Callable[[str], Any] | None = print, runner: str = DEFAULT_RUNNER,
              dry_run: bool = False, plots: bool = True) -> BatchResult:
    """Fit every video of a manifest; resumable.

    manifest: a .csv or .toml path (see fitode.batch.manifest) or a loaded Manifest.
    out: the batch's folder (default `<manifest stem>-results` beside the manifest).
    executor: "local" (a process pool of `workers`, default the usable cores), "ray" (the cluster
        at `address`, or a private local instance), or an Executor object.
    force: run every job again. retry_failed: run jobs that failed before with the same settings
        (the default; False keeps them failed). defaults: values for keys the manifest leaves unset.
    runner: "module:function" called as run_job(video, out_dir, progress=False, log=None, **kwargs).
    dry_run: plan and report, run nothing, write nothing. plots False: no job draws its pictures
    (the same numbers; a job's settings hash does not cover it).
    """
    t0 = time.perf_counter()
    man = manifest if isinstance(manifest, Manifest) else load_manifest(manifest, defaults)
    out_dir = Path(out) if out is not None else default_out_dir(man.path)
    say = log or (lambda *_: None)
    # before touching the out dir: a missing Ray or a bad --workers must leave nothing behind
    exe = executor if not isinstance(executor, str) else (
        None if dry_run and executor == "local" else make_executor(executor, workers, address))
    lock = _claim(out_dir, man, dry_run)
    try:
        return _run(man, out_dir, say, exe, force=force, retry_failed=retry_failed, progress=progress,
                    runner=runner, dry_run=dry_run, t0=t0, plots=plots)
    finally:
        if lock is not None:
            lock.close()


def _run(man: Manifest, out_dir: Path, say, exe: Executor | None, *, force: bool, retry_failed: bool,
         progress: bool, runner: str, dry_run: bool, t0: float, plots: bool) -> BatchResult:
    rows: dict[str, SummaryRow] = {}
    to_run: list[Job] = []
    for job in man.jobs:
        row, reusable = _plan_row(job, out_dir, man)
        if reusable and not force:
            row.reused = True
        elif row.status == "failed" and not retry_failed and not force and row.details.get("hash_match"):
            pass
        else:
            row.status, row.error, row.parameters, row.details, row.warnings = "pending", None, {}, {}, []
            row.reused = False
            to_run.append(job)
        row.details.pop("hash_match", None)
        rows[job.name] = row

    reused = [n for n, r in rows.items() if r.reused]
    kept = len(rows) - len(reused) - len(to_run)
    plan = (f"{len(man.jobs)} job{'s' if len(man.jobs) != 1 else ''}: {len(reused)} reused"
            + (f", {kept} failed before (kept)" if kept else "") + f", {len(to_run)} to run")
    if dry_run:
        say(plan + f"; out: {out_dir}")
        for job in to_run:
            say(f"  would run {job.name}: {job.video.name}  {_short(job.kwargs)}")
        return BatchResult(out_dir, list(rows.values()), aggregate(list(rows.values())), [], reused,
                           time.perf_counter() - t0)
    try:
        if hasattr(exe, "start") and to_run:
            exe.start()  # Ray: connect first, so the plan line can say how many CPUs the cluster has
        return _execute(man, out_dir, say, exe, plan, rows, to_run, reused, progress, runner, t0, plots)
    finally:
        if hasattr(exe, "stop"):
            exe.stop()


def _execute(man: Manifest, out_dir: Path, say, exe: Executor, plan: str, rows: dict[str, SummaryRow],
             to_run: list[Job], reused: list[str], progress: bool, runner: str, t0: float,
             plots: bool) -> BatchResult:
    say(plan + (f" on {exe.describe()}" if to_run else "") + f"; out: {out_dir}")

    meta = {"manifest": str(man.path), "out": str(out_dir), "started": _now(),
            "executor": exe.describe() if to_run else None}
    ordered = list(rows.values())
    write_summary(out_dir, ordered, meta)
    bar = _Progress(len(rows), sum(r.status in ("complete", "incomplete", "failed") for r in ordered),
                    counts(ordered), enabled=progress)
    ran: list[str] = []

    def on_start(task: Task) -> None:
        bar.started(task.job.name)

    def on_done(task: Task, outcome: JobOutcome) -> None:
        row = rows[task.job.name]
        _apply(row, outcome)
        _write_job_file(out_dir / task.job.name, task.job, outcome)
        ran.append(task.job.name)
        write_summary(out_dir, ordered, {**meta, "updated": _now()})
        bar.finished(task.job.name, outcome.status)

    tasks = [Task(job, out_dir / job.name, runner, plots=plots) for job in to_run]
    try:
        if tasks:
            exe.run(tasks, on_start, on_done)
    except KeyboardInterrupt:
        write_summary(out_dir, ordered, {**meta, "updated": _now(), "interrupted": True})
        bar.close()
        raise
    bar.close()
    result = BatchResult(out_dir, ordered, aggregate(ordered), ran, reused, time.perf_counter() - t0)
    write_summary(out_dir, ordered, {**meta, "finished": _now(), "wall_s": round(result.wall_s, 3)})
    return result


# --- planning -----------------------------------------------------------------------------

def _claim(out_dir: Path, man: Manifest, dry_run: bool):
    """The out dir is the batch's: new, empty, or one it made before (batch.json says so).

    Returns an open lock file (None for a dry run): two batches writing one folder would each
    clear the other's running jobs.
    """
    marker = out_dir / MARKER
    if out_dir.exists() and not out_dir.is_dir():
        raise FitodeError(f"--out {out_dir} is a file")
    if out_dir.is_dir() and any(out_dir.iterdir()) and not marker.is_file():
        raise FitodeError(f"{out_dir} is not empty and is not a fitode batch folder (no {MARKER}); "
                          "choose another --out")
    if not out_dir.is_dir():
        from fitode.output import check_writable
        check_writable(out_dir)  # /proc/x, a path through a file: one line before any job
    if dry_run:
        return None
    out_dir.mkdir(parents=True, exist_ok=True)
    lock = _lock(out_dir / LOCK)
    info = {"manifest": str(man.path), "created": _now(), "jobs": [j.name for j in man.jobs]}
    if marker.is_file():
        try:
            info["created"] = json.loads(marker.read_text()).get("created", info["created"])
        except (OSError, ValueError):
            pass
    write_json(info, marker)
    return lock


def _lock(path: Path):
    handle = open(path, "a+")
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        return handle
    try:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.seek(0)
        holder = handle.read().strip()
        handle.close()
        raise FitodeError(f"another fitode batch is writing {path.parent}"
                          + (f" (pid {holder})" if holder else "") + "; wait for it or choose another --out") from None
    handle.seek(0)
    handle.truncate()
    handle.write(str(os.getpid()))
    handle.flush()
    return handle


def _plan_row(job: Job, out_dir: Path, man: Manifest) -> tuple[SummaryRow, bool]:
    """The job's row as its folder stands, and whether its result can be reused."""
    try:
        video = job.video.relative_to(man.path.parent).as_posix()
    except ValueError:
        video = str(job.video)
    row = SummaryRow(name=job.name, setting=job.setting, video=video, truth=dict(job.truth), folder=job.name)
    folder = out_dir / job.name
    state = _read_json(folder / JOB_FILE)
    if not isinstance(state, dict):
        return row, False
    same = state.get("hash") == job.settings_hash
    row.details["hash_match"] = same
    if not same:
        return row, False
    row.status = state.get("status", "pending")
    row.error = state.get("error")
    row.wall_s = state.get("wall_s")
    row.warnings = list(state.get("warnings") or [])
    if row.status != "complete":
        return row, False
    report = _read_json(folder / "result.json")
    status, problem = check_report(report) if report is not None else ("failed", "result.json is missing or unreadable")
    if status != "complete":
        row.status, row.error = "pending", problem
        return row, False
    row.parameters = report_parameters(report)
    row.details.update(report_details(report))
    return row, True


def _apply(row: SummaryRow, outcome: JobOutcome) -> None:
    row.status, row.error, row.wall_s = outcome.status, outcome.error, outcome.wall_s
    row.parameters, row.warnings, row.reused = dict(outcome.parameters), list(outcome.warnings), False
    row.details = dict(outcome.details)


def _write_job_file(folder: Path, job: Job, outcome: JobOutcome) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    state = {"name": job.name, "hash": job.settings_hash, "status": outcome.status, "error": outcome.error,
             "wall_s": round(outcome.wall_s, 3), "finished": _now(), "host": outcome.host, "pid": outcome.pid,
             "parameters": outcome.parameters, "warnings": outcome.warnings, "settings": job.fingerprint,
             "manifest_row": job.where}
    if outcome.traceback:
        state["traceback"] = outcome.traceback
    from fitode._version import __version__
    state["fitode"] = __version__
    write_json(state, folder / JOB_FILE, default=str)  # default: a settings value JSON has no type for


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _short(kwargs: Mapping[str, Any]) -> str:
    return " ".join(f"{k}={v}" for k, v in kwargs.items())


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


class _Progress:
    """One bar over jobs; its postfix counts done, failed and running."""

    def __init__(self, total: int, initial: int, start_counts: dict[str, int], enabled: bool):
        self.done = start_counts.get("complete", 0)
        self.failed = start_counts.get("failed", 0) + start_counts.get("incomplete", 0)
        self.running: set[str] = set()  # a set: a job retried after a worker death starts twice
        self.bar = None
        if enabled:
            from tqdm.auto import tqdm
            self.bar = tqdm(total=total, initial=initial, desc="batch", unit="job", dynamic_ncols=True)
            self._post()

    def _post(self) -> None:
        if self.bar is not None:
            self.bar.set_postfix(done=self.done, failed=self.failed, running=len(self.running), refresh=True)

    def started(self, name: str) -> None:
        self.running.add(name)
        self._post()

    def finished(self, name: str, status: str) -> None:
        self.running.discard(name)
        if status == "complete":
            self.done += 1
        else:
            self.failed += 1
        if self.bar is not None:
            self.bar.set_postfix(done=self.done, failed=self.failed, running=len(self.running), refresh=False)
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
