"""Worker processes that start warm and stop at once, for the batch's local executor and the benchmarks.

Workers are never forked from the driver: a forked torch (its thread pools, its allocator) is not
safe to use. The forkserver is a clean process that imports the heavy libraries once (importing
starts no threads) and forks each worker from there, so a worker starts in milliseconds instead
of re-importing torch for seconds, which matters when a pool is rebuilt after a death.

Ctrl-C belongs to the driver: workers ignore SIGINT, and the driver stops them itself, at once,
where concurrent.futures would let the running jobs finish first.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import signal
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any, Callable

# fitode.batch.warm imports the heavy modules inside try blocks: a module that fails to import
# must not take the forkserver (and so every worker) down.
PRELOAD = ("fitode.batch.warm",)


def worker_context(start_method: str | None = None):
    """The multiprocessing context for workers: forkserver (preloaded) where there is one, else spawn."""
    method = start_method or ("forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn")
    ctx = mp.get_context(method)
    if method == "forkserver":
        ctx.set_forkserver_preload(list(PRELOAD))
    return ctx


def init_worker(threads: int = 1) -> None:
    """Worker start-up: no SIGINT, headless plots, and `threads` torch threads (one, so that
    workers do not fight over the cores, unless a benchmark measures more)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.setdefault("MPLBACKEND", "Agg")
    if threads <= 1:
        from .job import single_thread

        single_thread()
    else:
        import torch

        torch.set_num_threads(int(threads))


class _Tracking:
    """A multiprocessing context that remembers the processes it makes.

    The executor launches its workers through the context it is given (that is what mp_context is
    for), so this sees every worker, even one still starting, without reaching into the executor.
    """

    def __init__(self, context):
        self._context = context
        self.processes: list = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._context, name)

    def Process(self, *args: Any, **kwargs: Any):  # noqa: N802 - the context's own name
        proc = self._context.Process(*args, **kwargs)
        self.processes.append(proc)
        return proc


class WorkerPool:
    """A ProcessPoolExecutor whose workers can be stopped now.

    Use it as a context manager: leaving the block by an exception (KeyboardInterrupt above all)
    terminates the workers before the pool is shut down.
    """

    def __init__(self, workers: int, context=None, initializer: Callable[..., None] = init_worker,
                 initargs: tuple = ()):
        self._context = _Tracking(context or worker_context())
        self.executor = ProcessPoolExecutor(max_workers=workers, mp_context=self._context, initializer=initializer,
                                            initargs=initargs)

    def submit(self, fn: Callable[..., Any], *args: Any) -> Future:
        return self.executor.submit(fn, *args)

    def terminate(self) -> None:
        for proc in self._context.processes:
            try:
                proc.terminate()
            except Exception:  # noqa: BLE001 - already gone (or never started)
                pass

    def __enter__(self) -> "WorkerPool":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self.terminate()
        self.executor.shutdown(wait=True, cancel_futures=True)
