"""The stages of a fit, and what Ctrl-C or SIGTERM in each leaves: nothing finished is lost.

A fit runs in STAGES. Training (with the measurement's own checks) makes the estimates; the
calibration, the intervals and the assessment judge them; the pictures show them. An
interruption in a stage after training keeps the estimates: the stage raises Stopped, a
KeyboardInterrupt that carries the FitResult, its verdicts AMBIGUOUS and saying which checks
were left undone, and result.meta["stopped"] = {"stage", "undone"}. `fitode VIDEO` then writes
result.json ("status": "interrupted", "stage") and estimates.csv before anything else; a second
Ctrl-C stops at once.

FITODE_HOLD_AT=STAGE (a test hook, read only here): the process says "fitode: holding at STAGE"
on stderr when it reaches that stage (training: where training and its checks have just ended,
the signal still waiting for a safe point) and waits there (up to HOLD_S seconds) for a signal, so
that a test can signal a real `fitode VIDEO` inside any stage without depending on timing.
"""
from __future__ import annotations

import contextlib
import os
import sys
import time
from typing import Any, Iterator

STAGES = ("training", "calibration", "intervals", "assessment", "pictures")
# what each stage judging the estimates does, as a verdict's reason names it
CHECKS = {"calibration": "the calibration", "intervals": "the 95% interval",
          "assessment": "the checks behind the verdict"}
HOLD_ENV = "FITODE_HOLD_AT"
HOLD_S = 120.0


class Stopped(KeyboardInterrupt):
    """Ctrl-C or SIGTERM after training finished: .result has the estimates, .stage where it stopped."""

    def __init__(self, result: Any, stage: str):
        super().__init__(f"interrupted during the {stage}")
        self.result, self.stage = result, stage


def reached(stage: str) -> None:
    """Mark the start of a stage; under FITODE_HOLD_AT=stage, wait here for a signal."""
    if os.environ.get(HOLD_ENV) != stage:
        return
    from fitode.train import interrupts
    print(f"fitode: holding at {stage}", file=sys.stderr, flush=True)
    deadline = time.monotonic() + HOLD_S
    while time.monotonic() < deadline:
        time.sleep(0.02)
        interrupts.check()  # where signals wait for a safe point, this is one


@contextlib.contextmanager
def stage(result: Any, name: str, *, calibrating: bool = False) -> Iterator[None]:
    """A stage after training: an interruption inside it keeps the result (see stop) and raises
    Stopped. calibrating: a calibration was asked for (else it is no check left undone)."""
    try:
        reached(name)
        yield
    except Stopped:
        raise
    except KeyboardInterrupt:
        stop(result, name, calibrating=calibrating)
        raise Stopped(result, name) from None


def stop(result: Any, name: str, *, calibrating: bool = False, first_undone: str | None = None) -> None:
    """Mark a result interrupted in stage `name`: every verdict AMBIGUOUS where a check it rests on
    was left undone (from stage first_undone, default `name`, on), saying which."""
    later = STAGES[STAGES.index(first_undone or name):]
    undone = [CHECKS[s] for s in later if s in CHECKS and (calibrating or s != "calibration")]
    result.meta["interrupted"] = True
    result.meta["stopped"] = {"stage": name, "undone": undone}
    if not undone:
        return
    why = f"interrupted during the {name}; not made: {_and(undone)}"
    for p in result.parameters:
        result.verdicts[p] = {"verdict": "ambiguous", "reason": why}


def fitted(fit_frames, *args, calibrating: bool = False, **kw) -> Any:
    """fit_frames(*args, **kw) with Ctrl-C and SIGTERM kept for the moment training and the
    measurement's checks end: a signal in the checks after training (a trajectory refit, a
    perspective check) then stops the fit with its estimates (Stopped in "training") instead of
    losing them. A second signal, or one the training loop takes at its own safe point, stops at once."""
    from fitode.train import interrupts
    with interrupts.deferred_signals():
        result = fit_frames(*args, **kw)
        if result.meta.get("interrupted"):  # the training loop took the signal: the assessment says so
            return result
        try:
            reached("training")  # the test hook holds where training and its checks have just ended
            interrupts.check()  # the earlier handler learns which signal it was (SIGTERM's exit status)
        except KeyboardInterrupt:
            stop(result, "training", calibrating=calibrating, first_undone="calibration")
            raise Stopped(result, "training") from None
    return result


def mark_report(report: dict, result: Any) -> None:
    """result.json of an interrupted result: "status" interrupted, the "stage", and why ("error")."""
    if not result.meta.get("interrupted"):
        return
    stage = (result.meta.get("stopped") or {}).get("stage", "training")
    stopped = [r for r in result.runs if r.status == "interrupted"]
    where = f"run {stopped[0].index + 1} at step {stopped[0].steps}" if stopped else f"the {stage}"
    report["status"], report["stage"] = "interrupted", stage
    report["error"] = f"interrupted in {where}"


def _and(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]
