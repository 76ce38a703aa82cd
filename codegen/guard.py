"""Explaining a non-finite rollout: which sub-expression went NaN/inf first, where, and why.

Policy: a rollout never hands NaN or inf on silently. The block checks its output with one
`torch.isfinite(out).all()` per forward (one reduction and, on CUDA, one sync). Only when that
fails does this module replay the rollout without gradients, checking every vector-field
evaluation, and evaluate every sub-expression of the equation (children first) at the state
where the first non-finite derivative appeared. The first sub-expression that is non-finite
while all of its inputs are finite is the culprit: "sqrt(h) = nan at frame 12 (window 3:
h = -0.0312)". Other cases: a constant that is already non-finite, non-finite encoded frames, a
state that overflows in the integrator's own arithmetic.
"""
from __future__ import annotations

import torch

from .errors import NonFiniteError
from .integrators import Integrator
from .source import VectorField


class _Found(Exception):
    def __init__(self, y: torch.Tensor):
        self.y = y


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _first_bad(t: torch.Tensor) -> tuple[int, float] | None:
    bad = ~torch.isfinite(t)
    if not bad.any():
        return None
    flat = bad.reshape(-1).nonzero()[0, 0].item()
    return flat, t.reshape(-1)[flat].item()


def _state_problem(layout, y: torch.Tensor, frame: int, what: str) -> NonFiniteError | None:
    bad = ~torch.isfinite(y)
    if not bad.any():
        return None
    b, i = (bad.reshape(-1, y.shape[-1]).nonzero()[0]).tolist()
    v = y.reshape(-1, y.shape[-1])[b, i].item()
    label = layout.slots[i].label
    return NonFiniteError(f"{label} {what} ({_fmt(v)}) at frame {frame} (window {b})",
                          term=label, frame=frame, window=b, values={label: v})


def _culprit(field: VectorField, y: torch.Tensor, consts, frame: int) -> NonFiniteError:
    labels, fn, deps = field.subterms()
    yb = y.reshape(-1, y.shape[-1])
    values = fn(yb, *consts)
    for label, value, inputs in zip(labels, values, deps):
        value = torch.as_tensor(value)
        found = _first_bad(value.expand(yb.shape[:-1]) if value.dim() == 0 else value)
        if found is None:
            continue
        b, v = found
        ins = {}
        for name, kind, idx in inputs:
            ins[name] = yb[b, idx].item() if kind == "slot" else torch.as_tensor(consts[idx]).reshape(-1)[0].item()
        detail = ", ".join(f"{k} = {_fmt(x)}" for k, x in ins.items())
        return NonFiniteError(f"{label} = {_fmt(v)} in the step to frame {frame} (window {b}: {detail})",
                              term=label, frame=frame, window=b, values=ins)
    # Every sub-expression is finite but the stacked derivative is not: cannot happen unless the
    # printer and the sub-expression list disagree; still say where.
    return NonFiniteError(f"the equation's right-hand side is not finite at frame {frame}", frame=frame)


def explain_nonfinite(field: VectorField, integrator: Integrator, y0: torch.Tensor, consts,
                      n_frames: int, dt: float, substeps: int, frame_offset: int = 0) -> NonFiniteError:
    """Replay a rollout that produced non-finite values and say what went wrong first."""
    layout = field.layout
    with torch.no_grad():
        for name, c in zip(layout.constants, consts):
            found = _first_bad(torch.as_tensor(c))
            if found is not None:
                return NonFiniteError(f"constant {name} is {_fmt(found[1])}", term=name, values={name: found[1]})
        problem = _state_problem(layout, y0, frame_offset, "is not finite in the initial state")
        if problem is not None:
            return problem
        consts = tuple(c.detach() if isinstance(c, torch.Tensor) else c for c in consts)

        def f(yy):
            out = field.fn(yy, *consts)
            if not torch.isfinite(out).all():
                raise _Found(yy)
            return out

        h = float(dt) / substeps
        y = y0.detach()
        for t in range(1, n_frames):
            frame = frame_offset + t
            for _ in range(substeps):
                try:
                    y_new = integrator.step(f, y, h)
                except _Found as hit:
                    problem = _state_problem(layout, hit.y, frame, "overflowed")
                    return problem if problem is not None else _culprit(field, hit.y, consts, frame)
                problem = _state_problem(layout, y_new, frame, "overflowed")
                if problem is not None:
                    return problem
                y = y_new
    return NonFiniteError("the rollout produced non-finite values that a replay did not reproduce")

