"""What the benchmarks share: where they write, the machine they ran on, a process pool of
single-threaded workers (fitode.batch.pool's, as `fitode batch` uses), a per-step recorder,
plain-text tables and small statistics.

Every benchmark module (bench/<name>.py) exposes `add_arguments(parser)` and `run(args) -> int`,
so `fitode bench NAME` (fitode/cmd_bench.py) and `python bench/<name>.py` parse the same flags;
`script_main` is the second of those entry points.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time
from concurrent.futures import as_completed
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from fitode.batch.pool import WorkerPool
from fitode.jsonio import write_json

BENCH_DIR = Path(__file__).resolve().parent
DEFAULT_OUT = BENCH_DIR / "out"


# ----------------------------------------------------------------------------- entry points
def add_common_arguments(parser: argparse.ArgumentParser, *, workers: int | None = 2) -> None:
    """--quick, --out and (for benchmarks that run a pool) --workers."""
    parser.add_argument("--quick", action="store_true",
                        help="a tiny setting for smoke tests (seconds); its numbers mean nothing")
    parser.add_argument("--out", default=str(DEFAULT_OUT), metavar="DIR",
                        help=f"folder for the JSON record (default {DEFAULT_OUT})")
    if workers is not None:
        parser.add_argument("--workers", type=int, default=workers, metavar="N",
                            help=f"worker processes, each with one torch thread (default {workers})")


def script_main(module_doc: str | None, add_arguments: Callable, run: Callable, argv: Sequence[str] | None = None) -> int:
    """`python bench/<name>.py ...`: the same flags as `fitode bench <name>`, one-line errors."""
    from fitode.errors import FitodeError

    first = (module_doc or "").strip().splitlines()[0] if module_doc else None
    parser = argparse.ArgumentParser(description=first, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return int(run(args) or 0)
    except FitodeError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def pick(text: str, known: Sequence[str], flag: str) -> list[str]:
    """The names in a comma-separated option (--scenes a,b), each one of `known`, at least one."""
    from fitode.errors import FitodeError

    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise FitodeError(f"{flag}: unknown {', '.join(unknown) or '(none given)'}; choose from {', '.join(known)}")
    return names


def check_positive(value: int | None, flag: str) -> None:
    from fitode.errors import FitodeError

    if value is not None and value < 1:
        raise FitodeError(f"{flag} must be a positive integer, got {value}")


# ----------------------------------------------------------------------------- records
def machine_info() -> dict[str, Any]:
    """What the numbers depend on: CPUs, load (other processes slow every timing), versions, commit."""
    import torch

    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cpus = os.cpu_count() or 1
    info = {
        "date": _dt.datetime.now().isoformat(timespec="seconds"),
        "cpus": cpus,
        "load_avg": [round(v, 2) for v in os.getloadavg()],
        "python": platform.python_version(),
        "torch": torch.__version__,
        "numpy": np.__version__,
        "machine": platform.machine(),
        "processor": platform.processor() or None,
        "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
    }
    info.update(git_state())
    return info


def git_state() -> dict[str, Any]:
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=BENCH_DIR, capture_output=True, text=True,
                              timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=BENCH_DIR,
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return {}
    if head.returncode != 0:
        return {}
    return {"commit": head.stdout.strip(), "dirty": bool(dirty.stdout.strip())}


def write_record(record: Mapping[str, Any], out: str | Path, name: str) -> Path:
    """Write <out>/<name>.json (NaN and inf as null: JSON has neither)."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    return write_json(record, folder / f"{name}.json")


def read_record(path: str | Path) -> dict[str, Any]:
    """A record that write_record wrote, for --report: the tables again without running anything."""
    from fitode.errors import FitodeError

    path = Path(path)
    if not path.is_file():
        raise FitodeError(f"--report {path}: no such file")
    try:
        return json.loads(path.read_text())
    except ValueError as exc:
        raise FitodeError(f"--report {path}: not a benchmark record ({exc})") from None


def report_and_write(record: Mapping[str, Any], out: str | Path, name: str,
                     print_report: Callable[[Mapping[str, Any]], None]) -> int:
    """The end of a benchmark's run: its tables, then <out>/<name>.json, and where that went."""
    print_report(record)
    print(f"wrote {write_record(record, out, name)}")
    return 0


def reprinted(args: argparse.Namespace, print_report: Callable[[dict[str, Any]], None]) -> bool:
    """--report PATH: print_report on that earlier record (True), so a benchmark's run can stop
    there; False when no --report was given."""
    if not getattr(args, "report", None):
        return False
    print_report(read_record(args.report))
    return True


def peak_rss_mb() -> float:
    """This process's peak resident memory so far (Linux reports KiB, macOS bytes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2 ** 20 if sys.platform == "darwin" else peak / 1024


def current_rss_mb() -> float:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20
    except OSError:
        return math.nan


# ----------------------------------------------------------------------------- pool
def run_pool(fn: Callable[[Any], Any], tasks: Sequence[Any], workers: int,
             on_done: Callable[[int, Any], None] | None = None) -> list[Any]:
    """fn(task) for every task, in `workers` single-threaded processes (inline when workers == 1).

    Results come back in the order of `tasks`; on_done(index, result) is called as each finishes.
    fn must be a module-level function of an importable module (the pool pickles it by name).
    Ctrl-C stops the workers at once rather than letting the running tasks finish.
    """
    results: list[Any] = [None] * len(tasks)
    if workers <= 1 or len(tasks) <= 1:
        from fitode.batch.job import single_thread

        os.environ.setdefault("MPLBACKEND", "Agg")
        single_thread()  # inline, so that the timings match a one-threaded worker's
        for i, task in enumerate(tasks):
            results[i] = fn(task)
            if on_done is not None:
                on_done(i, results[i])
        return results
    with WorkerPool(min(workers, len(tasks))) as pool:
        futures = {pool.submit(fn, task): i for i, task in enumerate(tasks)}
        for fut in as_completed(futures):
            i = futures[fut]
            results[i] = fut.result()
            if on_done is not None:
                on_done(i, results[i])
    return results


def run_isolated(fn: Callable[[Any], Any], task: Any, threads: int = 1) -> Any:
    """fn(task) in a fresh process with `threads` torch threads: its peak memory is its own."""
    with WorkerPool(1, initargs=(threads,)) as pool:
        return pool.submit(fn, task).result()


def ran_on(record: Mapping[str, Any]) -> str:
    """The end of a report's last line: the machine and how long the whole benchmark took."""
    m = record["machine"]
    return f"{m['cpus']} CPUs (load {m['load_avg'][0]}): {record['wall_s']:.0f} s wall"


def progress(line: str) -> None:
    """Progress goes to stderr, so stdout holds only the tables."""
    print(line, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- training records
class StepRecorder:
    """A fitode.fit callback that keeps every step of every restart and when the trainer handed it
    over, so even a fit that raised (every restart failed) leaves its history. The trainer hands
    steps over every check_every steps, so the times are those of the hand-overs."""

    def __init__(self, names: Sequence[str]):
        from fitode.train.history import History
        self.runs: dict[int, Any] = {}
        self.t: list[float] = []
        self.t0 = time.perf_counter()
        self._new = lambda: History.for_constants(names)

    def __call__(self, info) -> None:
        self.t.append(time.perf_counter())
        self.runs.setdefault(info.run, self._new()).append(info.step, info.loss, info.mse, info.kl, info.constants)

    def history(self, run: int = 0, every: int = 10) -> dict[str, Any]:
        h = self.runs.get(run)
        return h.thinned(every).to_dict() if h is not None else {}


# ----------------------------------------------------------------------------- statistics
def mean_std(values: Iterable[float]) -> tuple[float, float, int]:
    """Mean and (population) standard deviation of the finite values, and how many there were."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    if v.size == 0:
        return math.nan, math.nan, 0
    return float(v.mean()), float(v.std()), int(v.size)


def rel_err(value: float, truth: float) -> float:
    """Signed relative error (value - truth) / |truth|."""
    if value is None or not math.isfinite(value) or truth == 0:
        return math.nan
    return (value - truth) / abs(truth)


def pm(mean: float, std: float, digits: int = 3) -> str:
    if not math.isfinite(mean):
        return "-"
    return f"{mean:.{digits}f} +- {std:.{digits}f}" if math.isfinite(std) else f"{mean:.{digits}f}"


def pct(x: float, digits: int = 2, signed: bool = True) -> str:
    if x is None or not math.isfinite(x):
        return "-"
    return f"{100 * x:+.{digits}f}%" if signed else f"{100 * x:.{digits}f}%"


def num(x: Any, digits: int = 3) -> str:
    if x is None:
        return "-"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    if not math.isfinite(x):
        return "-"
    return f"{x:.{digits}g}" if abs(x) >= 1e4 or (x != 0 and abs(x) < 1e-3) else f"{x:.{digits}f}"


# ----------------------------------------------------------------------------- tables
def format_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[tuple[str, str]],
                 title: str | None = None) -> str:
    """A plain-text table. columns: (header, key) pairs; each row's values are already strings
    (or are str()-ed). Text columns are left-aligned, the rest right-aligned."""
    cells = [[str(r.get(key, "")) for _, key in columns] for r in rows]
    heads = [h for h, _ in columns]
    widths = [max([len(h)] + [len(c[j]) for c in cells]) for j, h in enumerate(heads)]
    numeric = [all(_looks_numeric(c[j]) for c in cells) for j in range(len(heads))]

    def line(vals):
        return "  ".join(v.rjust(w) if n else v.ljust(w) for v, w, n in zip(vals, widths, numeric)).rstrip()

    out = [title] if title else []
    out += [line(heads), "  ".join("-" * w for w in widths)]
    out += [line(c) for c in cells]
    return "\n".join(out)


def _looks_numeric(text: str) -> bool:
    t = text.strip().replace("+-", "").replace("%", "").replace("/", "").replace(" ", "")
    if t in ("", "-"):
        return True
    try:
        float(t.lstrip("+"))
        return True
    except ValueError:
        return False


def all_finite(values: Iterable[Any]) -> bool:
    """True when every number in values (nested lists/dicts walked) is finite."""
    for v in values:
        if isinstance(v, Mapping):
            if not all_finite(v.values()):
                return False
        elif isinstance(v, (list, tuple)):
            if not all_finite(v):
                return False
        elif isinstance(v, (float, int, np.floating, np.integer)) and not isinstance(v, bool):
            if not math.isfinite(float(v)):
                return False
    return True
