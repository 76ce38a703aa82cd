"""Imported once by the local pool's forkserver, so every worker forked from it starts warm.

A worker's first job otherwise spends seconds importing torch, sympy, lark and matplotlib and
building the equation grammar; forked from a process that already did, it skips all that.
Nothing here may fail the import: a module that cannot load is simply left to the job, which
then reports the problem as its own error.
"""
import importlib
import os

# headless workers draw into files; the forkserver must not pick an interactive backend
os.environ.setdefault("MPLBACKEND", "Agg")

for _name in ("numpy", "torch", "torch.optim", "cv2", "sympy", "lark", "matplotlib",
              "matplotlib.figure", "matplotlib.backends.backend_agg", "fitode.plots", "fitode.pipeline", "fitode.api",
              "fitode.report", "fitode.video", "fitode.eqfile", "fitode.codegen", "fitode.train.trainer",
              "fitode.batch.job"):
    try:
        importlib.import_module(_name)
    except Exception:  # noqa: BLE001 - warming is best effort
        pass

try:  # the grammar is built on first use; importing starts no threads, neither does this
    from fitode.eqparse import parse as _parse

    _parse("x' = -k*x")
except Exception:  # noqa: BLE001
    pass
