"""torch's intra-op threads for a stretch of work: these models and matrices are small, and on a
busy machine two threads that wait on each other cost far more than they share (the observation's
look, an eigvalsh of 300 frames: 9.5 s on 2 threads against 0.09 s on 1 at load 11; a trajectory
fit of 39 frames 3.7x slower)."""
from __future__ import annotations

import contextlib


@contextlib.contextmanager
def torch_threads(n: int | None):
    """torch on n intra-op threads inside the block (None: as it is), restored after."""
    if n is None:
        yield
        return
    import torch
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)
