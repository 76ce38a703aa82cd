"""Another moving object where the reader's path does not follow the equation.

The reader takes the strongest change, or the object tracker's best-kept path (fitode.video.follow),
which is not always the object the equation is about: on the shared real drop read whole it follows
another moving thing than the ball. Where the user named no object and a constant came out NOT
TRUSTWORTHY, each other moving object the tracker sees (Track.objects) is fitted with the same
equation, and of those that move at least as far over their fitted frames as the reader's path did
over its own, the first whose constants are all trusted, or else one with none not trustworthy, is
taken instead, with a line that says so and names the flags that choose either way. What the user
named (--observe position@K, or any --observe) is never replaced.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable

import numpy as np

from fitode.errors import FitodeError

MODELS = ("position", "angle")  # the observations that read a place of the reader's track


def _counts(result) -> tuple[int, int]:
    verdicts = [v.get("verdict") for v in result.verdicts.values()]
    return verdicts.count("not trustworthy"), verdicts.count("trusted")


def _travel(result) -> float:
    """How far the fitted path moves over the frames fitted, in the state's units (the largest
    range of any state): a short, small stretch of anything fits some trajectory of the equation."""
    measured = np.asarray((result.meta.get("trajectory") or {}).get("measured") or [], dtype=float)
    if measured.size == 0:
        return 0.0
    return float(np.nanmax(np.ptp(measured.reshape(len(measured), -1), axis=0)))


def _unnamed(model) -> tuple[str, Any] | None:
    """(model name, the reader's track) where the observation reads a place of the reader's track
    (one of MODELS, for every state) without naming an object; None otherwise."""
    parts = list(getattr(model, "parts", {}).values()) or [model]
    names = {p.name for p in parts}
    if len(names) != 1 or any(getattr(p, "object", None) for p in parts):
        return None
    name, track = names.pop(), getattr(parts[0], "track", None)
    return (name, track) if name in MODELS and track is not None else None


def _doubted(result, plan) -> tuple[str, Any] | None:
    """_unnamed's (model name, track) where, besides, the fit ran whole and a constant came out not
    trustworthy: where another object may be the equation's; None otherwise."""
    read = _unnamed(plan.observation)
    if read is None or result.meta.get("interrupted") or not _counts(result)[0]:
        return None
    return read


def naming_line(result, plan) -> str | None:
    """Where a constant is not trustworthy and the reader's path came from one of several moving
    objects the observation did not name, the line that names them and the flag that reads each
    (Track.others); None otherwise."""
    read = _doubted(result, plan)
    return None if read is None else read[1].others(read[0])


def another_object(req, plan, result, fit: Callable[[Any], tuple[Any, Any]],
                   log: Callable[[str], None] | None = None):
    """(result, request, plan) of another moving object where the reader's path gives a constant
    that is not trustworthy and another object's path gives none (module docstring); None where
    the fit stays as it is. fit(request): (its plan, its result) on the same frames and track, as
    the first was made."""
    read = _doubted(result, plan)
    if req.observe is not None or read is None or len(read[1].objects) < 2:
        return None
    name, track = read
    say = log or (lambda _line: None)
    taken = track.taken()
    reach = _travel(result)
    best = None
    for k in range(1, len(track.objects) + 1):
        if k == taken:
            continue
        spec = f"{name}@{k}"
        other = replace(req, observe=spec, observe_source="another moving object: the reader's path does not "
                                                          "follow the equation")
        say(f"trying object {k} of {len(track.objects)}: the reader's path gives a constant that is not trustworthy")
        try:
            other_plan, fitted = fit(other)
        except FitodeError:
            continue
        except KeyboardInterrupt:
            # the reader's path was fitted and judged whole: its result is kept, marked interrupted
            from fitode.interrupted import Stopped
            result.meta["interrupted"] = True
            result.meta["stopped"] = {"stage": "assessment", "undone": []}
            raise Stopped(result, "assessment") from None
        bad, trusted = _counts(fitted)
        # and it moves at least as far along the equation as the reader's path where that was fitted:
        # the object a clip is about is the one whose motion the equation follows farthest
        if bad or fitted.meta.get("interrupted") or not fitted.meta.get("direct") or _travel(fitted) < reach:
            continue
        if best is None or trusted > best[0]:
            best = (trusted, k, spec, fitted, other, other_plan)
        if trusted == len(fitted.verdicts):
            break
    if best is None:
        return None
    _, k, spec, fitted, other, other_plan = best
    was = f"object {taken}" if taken else "a path none of theirs"
    back = f"--observe {name}@{taken}" if taken else f"--observe {name}"  # a model named: nothing is swapped
    fitted.warnings.insert(0, (
        f"read from object {k} of {len(track.objects)} (about x = {track.place(k)[0]:.0f} px), "
        f"not the reader's path ({was}), on which a constant was not trustworthy: the equation follows this one; "
        f"--observe {spec} says so, {back} reads the reader's"))
    return fitted, other, other_plan

