"""Model comparison: several candidate equations fitted to one clip, ranked by how well each
predicts stretches of the measured path it was not fitted on (fitode.train.crossval).

The clip is read once. The first candidate is planned and fitted as a single equation would be
(its observation model, the stretch of the clip one trajectory explains); every other candidate
is then fitted on the same frames, read by the same observation model, on its own stretch; then
every candidate whose stretch is not the widest span any of them explains is fitted again on
that span, so that none is scored only on the part of the clip it happens to fit. The
blocked cross-validation of every candidate runs on one measured path (each candidate reads it in
its own gauge, as its fit did), so the held-out errors are in one unit: the path as measured, not
as one candidate's perspective re-read it (the position observation's re-reading is fitted with
the equation, and a bend can stand in for a missing term).

Only a measured path (position, angle, brightness, size) can be compared: a free latent is
learned for each candidate in units of its own, so their held-out errors would measure
different signals.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from fitode.errors import FitodeError

FREE_LATENT = ("comparing equations needs a measured path (an observation of position, angle, brightness or size): "
               "with a free latent each candidate learns a signal in units of its own, so their held-out errors "
               "are not comparable; fit each equation alone, or give --observe")
# the least correlation of two candidates' measured paths for them to be one signal: a perspective
# re-reading (a bend of at most a few tens of percent at the ends) stays above it, another axis does not
SAME_PATH = 0.95


@dataclass
class CandidateFit:
    """One candidate equation of a comparison: its request, plan, fit and held-out errors."""

    equation: str  # as the user typed it
    request: Any  # fitode.api.FitRequest
    plan: Any = None  # fitode.train.plan.FitPlan
    result: Any = None  # fitode.train.result.FitResult; None where its fit failed
    held: Any = None  # fitode.train.crossval.HeldOut
    verdict: str = "failed"
    error: str | None = None  # why its fit or its cross-validation failed

    def to_dict(self) -> dict[str, Any]:
        params = {}
        if self.result is not None:
            for name, est in self.result.parameters.items():
                trust = self.result.verdicts.get(name, {}).get("verdict")
                params[name] = {"value": est.value, "interval": est.interval, "unit": est.unit, "trust": trust}
        return {"equation": self.equation, "parameters": params,
                "heldout_error": None if self.held is None or not math.isfinite(self.held.error) else self.held.error,
                "heldout": None if self.held is None else self.held.to_dict(),
                "verdict": self.verdict, "error": self.error}


@dataclass
class Comparison:
    """The candidates, the preferred one (None: the clip cannot tell) and the one reported."""

    candidates: list[CandidateFit]
    preferred: int | None
    reason: str
    stretch: tuple[int, int]
    blocks: int
    notes: list[str] = field(default_factory=list)

    @property
    def chosen(self) -> int:
        """The candidate whose fit is reported: the preferred one, else the first (the clip cannot tell)."""
        return self.preferred if self.preferred is not None else 0

    @property
    def result(self):
        return self.candidates[self.chosen].result

    def to_dict(self) -> dict[str, Any]:
        """result.json's `comparison` block."""
        reported = self.candidates[self.chosen].equation
        why = ("the preferred candidate's" if self.preferred is not None
               else "the first candidate's: this clip cannot tell the candidates apart")
        return {"candidates": [c.to_dict() for c in self.candidates],
                "preferred": None if self.preferred is None else self.candidates[self.preferred].equation,
                "reason": self.reason, "reported": reported, "parameters_are": why,
                "method": f"blocked cross-validation along time: {self.blocks} contiguous blocks of frames "
                          f"{self.stretch[0]}-{self.stretch[1]}, each predicted by one trajectory fitted to the rest; "
                          "error in spreads of the measured path",
                "stretch": list(self.stretch), "blocks": self.blocks, "notes": list(self.notes)}


def compare(requests: Sequence, frames, dt: float, *, track=None, geometry=None, time_offset: float = 0.0, callback=None,
            progress: bool = False, rate_std: float = 0.0, blocks: int | None = None,
            log: Callable[[str], None] | None = None, first_plan=None) -> Comparison:
    """Fit every candidate (fitode.api.requests: one FitRequest per equation, `equation` set as
    typed by requests' caller) on the frames (T, C, H, W) dt apart, cross-validate each along
    time and rank them (module docstring). first_plan: the first candidate's plan where the
    caller made it already; track and geometry: as fitode.api.plan takes them. FitodeError (one
    line) where the comparison cannot be made."""
    from fitode import api
    from fitode.train.crossval import BLOCKS, rank

    say = log or (lambda _line: None)
    blocks = BLOCKS if blocks is None else int(blocks)
    cands = [CandidateFit(equation=getattr(r, "equation", None) or r.system.text, request=r) for r in requests]
    first = cands[0]
    first.plan = first_plan or api.plan(first.request, frames, dt, track=track, geometry=geometry)
    if not first.plan.observation.may_measure:
        raise FitodeError(FREE_LATENT)
    options = dict(time_offset=time_offset, callback=callback, progress=progress, rate_std=rate_std)
    say(f"candidate 1 of {len(cands)}: {first.equation}")
    first.result = api.execute(first.request, first.plan, frames, **options)
    if not first.result.meta.get("direct"):
        why = first.result.meta.get("direct_failed")
        raise FitodeError(FREE_LATENT + (f" (the measured path could not be fitted: {why})" if why else ""))
    own = {0: _stretch_of(first.result)}
    for i, c in enumerate(cands[1:], start=1):
        say(f"candidate {i + 1} of {len(cands)}: {c.equation}")
        try:
            observe = _observe_like(first.plan.observation, first.request.system.states, c.request.system.states)
            c.request = replace(c.request, observe=observe, observe_source="the first candidate's, for the comparison")
            c.plan = api.plan(c.request, frames, dt, track=track, geometry=geometry)
        except FitodeError as exc:
            c.error = str(exc)
            continue
        if _fit(c, frames, options):
            own[i] = _stretch_of(c.result)
    # every candidate is scored on the span that any of them explains: a wrong equation's own
    # stretch is the part it happens to fit (a linear pendulum on a 50-degree swing keeps only the
    # small late swings, where the sine cannot be told from it)
    stretch = (min(a for a, _ in own.values()), max(b for _, b in own.values()))
    widest = max(own, key=lambda i: own[i][1] - own[i][0])
    st = dict(cands[widest].result.meta["stretch"])
    if own[widest] != stretch:
        st.update(start_frame=stretch[0], end_frame=stretch[1], start_s=stretch[0] * dt, end_s=stretch[1] * dt,
                  reason="the span the candidates' own stretches cover together")
    st["source"] = "the widest any candidate explains, for the comparison"
    for i, c in enumerate(cands):
        if i not in own:
            continue
        if own[i] != stretch:
            say(f"candidate {i + 1} of {len(cands)} again, on frames {stretch[0]}-{stretch[1] - 1}: {c.equation}")
            if not _fit(c, frames, options, stretch):
                continue
        c.result.meta["stretch"] = dict(st)
    if first.result is None:
        raise FitodeError(f"the first candidate could not be fitted on the comparison's stretch: {first.error}")
    # the path every candidate is scored on: as measured, not as a candidate's perspective re-read it
    # (a fall without drag re-read through a perspective bends the drag away: scored on its own
    # bent path it would win), so the first candidate whose fit read it straight gives it
    fitted = [c for c in cands if c.result is not None]
    source = next((c for c in fitted if not _bent(c.result)), first)
    base = np.asarray(source.result.latent, dtype=np.float64)[stretch[0]:stretch[1]]
    notes = [f"{c.equation!r}: its own fit read the path through a perspective "
             f"({c.result.checks['perspective']['bend_at_ends']:.0%} at the ends); every held-out error is on the "
             f"path as {'measured' if not _bent(source.result) else 'the first candidate read it'}"
             for c in fitted if _bent(c.result)]
    for c in fitted:
        x = _same_signal(base, source.plan, c.plan)
        own = _same_signal(np.asarray(c.result.latent, dtype=np.float64)[stretch[0]:stretch[1]], c.plan, c.plan)
        if _correlation(x, own) < SAME_PATH:
            raise FitodeError(f"the candidates read different paths from the clip ({source.equation!r} and "
                              f"{c.equation!r}: the states' names pick what is measured, x across and y up); "
                              "name the states alike")
        c.held, c.error = _held_out(c, x, blocks)
    ranking = rank([c.held if c.held is not None else _failed(blocks, stretch) for c in cands],
                   names=[repr(c.equation) for c in cands])
    for c, v in zip(cands, ranking.verdicts):
        c.verdict = v if c.held is not None else "failed"
    return Comparison(cands, ranking.preferred, ranking.reason, stretch, blocks, notes)


def _observe_like(observation, states: Sequence[str], other: Sequence[str]):
    """What makes another candidate's plan (states `other`) read the frames as the first one's
    (states `states`) did: its model's name, or one per state by position (the candidates' states
    may be named differently)."""
    parts = getattr(observation, "parts", None)
    if parts:
        return {o: parts[s].name for s, o in zip(states, other)}
    return observation.name


def _same_signal(latent: np.ndarray, made_for, read_by) -> np.ndarray:
    """The first candidate's measured latent as `read_by`'s plan reads the same columns: in the
    state's own units as it is, else standardised to that plan's prior (trainer._measured_latent)."""
    if read_by.observation.physical_units:
        return latent
    (m0, s0), (m1, s1) = made_for.prior, read_by.prior
    return m1 + s1 * (latent - m0) / s0


def _bent(result) -> bool:
    return bool((result.checks.get("perspective") or {}).get("apply"))


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a.reshape(len(a), -1), b.reshape(len(b), -1)
    if a.shape != b.shape:
        return 0.0
    out = []
    for i in range(a.shape[1]):
        if a[:, i].std() == 0 or b[:, i].std() == 0:
            return 0.0
        out.append(abs(float(np.corrcoef(a[:, i], b[:, i])[0, 1])))
    return min(out)


def _held_out(c: CandidateFit, x: np.ndarray, blocks: int):
    from fitode.eqparse.gauge import gauge_plan
    from fitode.train.crossval import held_out

    system, plan, traj = c.request.system, c.plan, c.result.meta["trajectory"]
    gauges = plan.observation.gauge_plan(gauge_plan(system))
    try:
        held = held_out(system, plan.params, x, plan.dt, traj["values"], fitted_gauge=traj.get("gauge"),
                        gauge=gauges, blocks=blocks, integrator=plan.config.integrator,
                        substeps=int(c.result.settings.get("substeps", plan.config.substeps)))  # the steps the fit settled on
    except ValueError as exc:  # too few frames for the blocks
        raise FitodeError(f"cannot cross-validate: {exc}") from None
    if not math.isfinite(held.error):
        return held, "a held-out fit left the equation's domain"
    return held, None


def _fit(c: CandidateFit, frames, options: Mapping, stretch: tuple[int, int] | None = None) -> bool:
    """Fit candidate c by its plan (on `stretch`, None: the one it finds), keeping its result, or
    its error where it fails or its measured path could not be fitted directly."""
    from fitode import api
    try:
        c.result = api.execute(c.request, c.plan, frames, stretch=stretch, **options)
    except FitodeError as exc:
        c.error, c.result = str(exc), None
        return False
    if not c.result.meta.get("direct"):
        c.error, c.result = "its measured path could not be fitted directly", None
        return False
    return True


def _stretch_of(result) -> tuple[int, int]:
    st = result.meta["stretch"]
    return int(st["start_frame"]), int(st["end_frame"])


def _failed(blocks: int, stretch: tuple[int, int]):
    from fitode.train.crossval import HeldOut, blocks_of
    return HeldOut(blocks_of(stretch[1] - stretch[0], blocks), np.full(blocks, math.inf))
