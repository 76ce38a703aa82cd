"""Where jobs run: a local process pool, or an existing Ray cluster.

Both take the same tasks and call the same `execute_job`, each job single-threaded and seeded
from its own row, so a batch gives the same numbers on either.

The local pool keeps at most `workers` jobs in flight, so when a worker dies (killed for memory,
a segfault, os._exit) the suspects are exactly the jobs that were running. The pool is then
broken (concurrent.futures cannot tell which job killed it); each suspect is run once more
alone in its own process, which either completes (it was a bystander) or dies again and is
marked failed with the exit status. A fresh pool takes the rest.
"""
from __future__ import annotations

import os
import signal
import socket
from collections import deque
from contextlib import contextmanager, nullcontext
from concurrent.futures import FIRST_COMPLETED, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing.connection import wait as wait_ready
from typing import Callable, Protocol, Sequence

from fitode.errors import FitodeError

from .job import JobOutcome, Task, execute_job, one_line, single_thread
from .pool import WorkerPool, init_worker, worker_context

OnStart = Callable[[Task], None]
OnDone = Callable[[Task, JobOutcome], None]


class Executor(Protocol):
    workers: int

    def describe(self) -> str: ...

    def run(self, tasks: Sequence[Task], on_start: OnStart, on_done: OnDone) -> None:
        """Run every task, calling on_done once per task; KeyboardInterrupt stops the workers and propagates."""


def available_cpus() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _died(task: Task, exitcode: int | None) -> JobOutcome:
    if exitcode is not None and exitcode < 0:
        try:
            sig = signal.Signals(-exitcode).name
        except ValueError:
            sig = f"signal {-exitcode}"
        why = f"the worker was killed by {sig}" + (" (out of memory?)" if exitcode == -signal.SIGKILL else "")
    elif exitcode is not None:
        why = f"the worker process exited with status {exitcode}"
    else:
        why = "the worker process died"
    return JobOutcome(name=task.job.name, status="failed", error=f"{why} while running this job")


class LocalExecutor:
    """A process pool on this machine: `workers` processes (default: the usable cores), one job each."""

    def __init__(self, workers: int | None = None, start_method: str | None = None):
        if workers is not None and workers < 1:
            raise FitodeError(f"--workers must be at least 1, got {workers}")
        self.workers = workers or available_cpus()
        self.context = worker_context(start_method)
        self.start_method = self.context.get_start_method()

    def describe(self) -> str:
        return f"{self.workers} local worker{'s' if self.workers != 1 else ''}"

    def run(self, tasks: Sequence[Task], on_start: OnStart, on_done: OnDone) -> None:
        queue = deque(tasks)
        while queue:
            suspects = self._pool_pass(queue, on_start, on_done)
            if suspects:
                self._isolated(suspects, on_start, on_done)

    def _pool_pass(self, queue: deque[Task], on_start: OnStart, on_done: OnDone) -> list[Task]:
        """Run tasks from the queue until it is empty or the pool breaks; returns the broken pool's suspects."""
        size = min(self.workers, len(queue))
        inflight: dict = {}
        suspects: list[Task] = []
        broken = False
        with WorkerPool(size, self.context) as pool:  # an exception (Ctrl-C) stops the workers at once
            while (queue and not broken) or inflight:
                while queue and len(inflight) < size and not broken:
                    task = queue.popleft()
                    try:
                        fut = pool.submit(execute_job, task)
                    except BrokenProcessPool:  # a worker died between two jobs
                        queue.appendleft(task)
                        broken = True
                        break
                    inflight[fut] = task
                    on_start(task)
                if not inflight:
                    break
                done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
                for fut in done:
                    task = inflight.pop(fut)
                    try:
                        outcome = fut.result()
                    except BrokenProcessPool:
                        suspects.append(task)
                        broken = True
                        continue
                    except Exception as exc:  # e.g. a task that cannot be pickled
                        outcome = JobOutcome(name=task.job.name, status="failed",
                                             error=one_line(f"could not run the job: {type(exc).__name__}: {exc}"))
                    on_done(task, outcome)
        return suspects

    def _isolated(self, tasks: list[Task], on_start: OnStart, on_done: OnDone) -> None:
        """Each task alone in its own process, up to `workers` at once, so a death names its job."""
        pending = deque(Task(t.job, t.out_dir, t.runner, attempt=t.attempt + 1, plots=t.plots) for t in tasks)
        running: dict = {}  # sentinel -> (process, connection, task)
        try:
            while pending or running:
                while pending and len(running) < self.workers:
                    task = pending.popleft()
                    recv, send = self.context.Pipe(duplex=False)
                    proc = self.context.Process(target=_isolated_main, args=(send, task))  # may start its own pool
                    proc.start()
                    send.close()
                    running[proc.sentinel] = (proc, recv, task)
                    on_start(task)
                ready = wait_ready(list(running) + [c for _, c, _ in running.values()])
                for key in list(running):
                    proc, conn, task = running[key]
                    if key not in ready and conn not in ready:
                        continue
                    outcome = None
                    try:
                        if conn.poll():
                            outcome = conn.recv()
                    except (EOFError, OSError):
                        outcome = None
                    proc.join(timeout=None if outcome is not None else 5)
                    if outcome is None and proc.is_alive():
                        continue  # readable only because of a partial message; wait for the rest
                    del running[key]
                    conn.close()
                    on_done(task, outcome if outcome is not None else _died(task, proc.exitcode))
        except BaseException:
            for proc, conn, _ in running.values():
                proc.terminate()
            for proc, conn, _ in running.values():
                proc.join(timeout=5)
                conn.close()
            raise


def _isolated_main(conn, task: Task) -> None:
    init_worker()
    outcome = execute_job(task)
    conn.send(outcome)
    conn.close()


class RayExecutor:
    """Ray tasks (one CPU each) on the cluster at `address`, or on a private local instance.

    The videos and the output folder must be at the same paths on every node (a shared file
    system), since each task reads its video and writes its folder where it runs.
    """

    def __init__(self, address: str | None = None, workers: int | None = None):
        try:
            import ray  # noqa: F401
        except ImportError:
            raise FitodeError("--executor ray needs Ray: pip install 'fitode[ray]'") from None
        self.address = address
        self.requested = workers
        self.workers = workers or 0
        self._owns = False
        self._host = _check_reachable(address) if address else None

    def describe(self) -> str:
        where = self.address or "a local Ray instance"
        return f"Ray at {where} ({self.workers} CPUs)"

    def start(self) -> None:
        import ray

        if not ray.is_initialized():
            kwargs = dict(log_to_driver=False, configure_logging=True, logging_level="WARNING")
            try:
                if self.address:
                    # a loopback-only cluster (one started as below) is reached through loopback too;
                    # Ray would otherwise swap 127.0.0.1 for this machine's public address
                    with _loopback_only() if self._host in _LOOPBACK else nullcontext():
                        ray.init(address=self.address, **kwargs)
                else:
                    with _loopback_only():
                        ray.init(num_cpus=self.requested or available_cpus(), include_dashboard=False, **kwargs)
            except Exception as exc:
                raise FitodeError(one_line(f"could not start or reach Ray: {_ray_reason(exc)}")) from None
            self._owns = True
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.workers = min(self.requested, cpus) if self.requested else cpus

    def stop(self) -> None:
        import ray

        if self._owns and ray.is_initialized():
            ray.shutdown()
        self._owns = False

    def run(self, tasks: Sequence[Task], on_start: OnStart, on_done: OnDone) -> None:
        import ray

        self.start()
        remote = ray.remote(num_cpus=1, max_retries=0)(_ray_main)
        queue = deque(tasks)
        inflight: dict = {}
        try:
            while queue or inflight:
                while queue and len(inflight) < self.workers:
                    task = queue.popleft()
                    inflight[remote.remote(task)] = task
                    on_start(task)
                ready, _ = ray.wait(list(inflight), num_returns=1)
                for ref in ready:
                    task = inflight.pop(ref)
                    try:
                        outcome = ray.get(ref)
                    except Exception as exc:  # the worker crashed, was killed for memory, the node left
                        outcome = JobOutcome(name=task.job.name, status="failed",
                                             error=one_line(f"Ray: {type(exc).__name__}: {_ray_reason(exc)}"))
                    on_done(task, outcome)
        except BaseException:
            for ref in inflight:
                try:
                    ray.cancel(ref, force=True)
                except Exception:
                    pass
            raise
        finally:
            self.stop()


_LOOPBACK = {"127.0.0.1", "localhost", "::1"}


def _check_reachable(address: str) -> str | None:
    """A typo in --address must fail in seconds: Ray itself retries an unreachable cluster for minutes.

    Returns the address's host (None for "auto" and other forms without host:port)."""
    rest = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit():
        return None
    host = host.strip("[]")
    try:
        with socket.create_connection((host, int(port)), timeout=10):
            pass
    except OSError as exc:
        raise FitodeError(f"cannot reach a Ray cluster at {address}: {exc.strerror or exc}") from None
    return host


@contextmanager
def _loopback_only():
    """A private Ray instance must not listen on the network.

    Ray resolves even `_node_ip_address="127.0.0.1"` to the machine's public address and binds
    its servers there. Its single-machine mode (the one it uses on macOS and Windows) takes the
    loopback address instead, and its servers then listen on 127.0.0.1 only. The processes ray.init
    starts inherit the variable; it is restored afterwards.
    """
    key = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
    old = os.environ.get(key)
    os.environ[key] = "0"
    constants = None
    try:
        from ray._private import ray_constants as constants
        saved = constants.ENABLE_RAY_CLUSTER
        constants.ENABLE_RAY_CLUSTER = False  # read at import time: ray may already be imported
    except (ImportError, AttributeError):
        constants = None
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = old
        if constants is not None:
            constants.ENABLE_RAY_CLUSTER = saved


def _ray_main(task: Task) -> JobOutcome:
    single_thread()
    return execute_job(task)


def _ray_reason(exc: BaseException) -> str:
    """First line of the exception, and of its causes: Ray's wrappers hide the reason (a missing
    authentication token, say) in __cause__."""
    parts, texts = [], []
    while exc is not None and len(parts) < 3:
        texts.append(str(exc))
        lines = [ln for ln in str(exc).strip().splitlines() if ln.strip() and "Traceback" not in ln]
        parts.append(lines[0] if lines else type(exc).__name__)
        exc = exc.__cause__
    if any("InvalidAuthToken" in t or "AuthenticationError" in t for t in texts):
        return (f"{parts[0]}: the cluster wants an authentication token: give it as RAY_AUTH_TOKEN or in "
                "~/.ray/auth_token (see Ray's token authentication)")
    return ": ".join(dict.fromkeys(parts))


def make_executor(kind: str, workers: int | None = None, address: str | None = None) -> Executor:
    if kind == "local":
        if address:
            raise FitodeError("--address is for --executor ray")
        return LocalExecutor(workers)
    if kind == "ray":
        return RayExecutor(address, workers)
    raise FitodeError(f"unknown executor '{kind}' (local or ray)")
