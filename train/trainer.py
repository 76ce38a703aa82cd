"""fit_frames: a plan's restarts, the batched training loop, selection, the checks and the FitResult.

The parts live beside it: the options in config.py, the loop in loop.py, the stopping rule in
stopping.py, the observation model (frames -> latent) in observe/, the gauge in gauge.py, the
choice of runs in selection.py.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace
from typing import Callable, Mapping, Sequence

import numpy as np
import torch

from fitode.codegen.constants import reparam_for
from fitode.eqparse import OdeSystem, ParamSpec, analyse
from fitode.eqparse.gauge import gauge_plan
from fitode.eqparse.identify import sign_odd
from fitode.eqparse.units import constant_units
from fitode.errors import TrainingError

from . import interrupts
from .config import TrainConfig
from .consistency import one_trajectory_check, whole_clip_check
from .loop import Callback, StepInfo, Trained, encode_all, train_restarts
from .observe import ObservationModel
from .observe.tracking import mended_caution
from .perspective import perspective_check
from .plan import FitPlan
from .result import Estimate, FitResult, RunRecord
from .score import dominant_period, separation_score
from .selection import select_runs, selection
from .starts import CANDIDATES, data_starts
from .direct import fit_path, fitted_path, full_fit, off_bounds, orientation, screen
from .steps import settle_substeps
from .joint import disagreement, fit_pieces, other_motions
from .pieces import Pieces, find_pieces
from .stretch import MIN_SEED, Stretch, at_rest, find_stretch, noise_level
from .threads import torch_threads as _threads  # the fit's threads (config.threads)
from .trajectory import SEGMENT, fit_trajectory, long_options
from .findings import Finding
from .latent_checks import video_checks

STRETCH_ITERATIONS = 20  # Levenberg-Marquardt steps per fit of the stretch search (warm-started)
DATA_STARTS = 2  # restarts that start from the data search (fitode.train.starts), when there are enough
SCORE_EXCLUDE = 2  # frames either side left out of the score's neighbours (see fitode.train.score)

__all__ = ["Callback", "StepInfo", "TrainConfig", "fit_frames", "restart_inits", "select_runs"]


def restart_inits(system: OdeSystem, params: Mapping[str, ParamSpec], n: int, seed: int,
                  fixed_init: Mapping[str, float] | None = None) -> list[dict[str, float]]:
    """Initial constants for n restarts, spread as in the paper.

    Run 0 starts from the user's value (fixed_init), else the equation file's init, else the
    default of fitode.codegen.constants; the others from seeded draws: uniform in [-10, 10] for an
    unbounded constant, log-uniform over three decades around the init for a one-sided bound,
    uniform inside two bounds. (fit_frames replaces some of the draws by starts from the data.)
    """
    rng = np.random.default_rng(seed)
    inits: list[dict[str, float]] = []
    for i in range(n):
        row = {}
        for name in system.learnable:
            spec = params.get(name, ParamSpec())
            rep, base = reparam_for(name, spec)
            if i == 0:
                row[name] = float(fixed_init[name]) if fixed_init and name in fixed_init else float(base)
            elif rep.lo is not None and rep.hi is not None:
                row[name] = float(rng.uniform(rep.lo, rep.hi))
            elif rep.lo is not None or rep.hi is not None:
                edge = rep.lo if rep.lo is not None else rep.hi
                sign = 1.0 if rep.lo is not None else -1.0
                gap = abs(base - edge) or 1.0
                row[name] = float(edge + sign * gap * 10 ** rng.uniform(-1.5, 1.5))
            else:
                row[name] = float(rng.uniform(-10.0, 10.0))
        inits.append(row)
    return inits


TURN_MISS = 1.1  # a line read the other way is taken where it fits about as well (_turn_pays)


def fit_frames(frames: torch.Tensor, plan: FitPlan, *, callback: Callback | None = None,
               progress: bool = False, stretch: tuple[int, int] | None = None, measurement=None) -> FitResult:
    """Every restart of the plan on raw float frames (T, C, H, W), trained on the first
    plan.n_train; the estimates and the measurement's checks (result.checks, with their findings).
    The verdicts are the assessment's (fitode.train.assess), made after any calibration.
    stretch: the [first, last) frames a measured path is fitted on, found before (for another
    candidate equation of a comparison, which must fit the same frames): no stretch is looked for.
    measurement: the frames as measure.measure read them for this plan (None: measured here)."""
    system, params, config, observation, dt = plan.system, plan.params, plan.config, plan.observation, plan.dt
    n_total, n_train = plan.n_frames, plan.n_train
    if frames.shape[0] != n_total:
        raise TrainingError(f"the plan is for {n_total} frames, got {frames.shape[0]}")
    device = torch.device(config.device)
    if measurement is None:
        from .measure import measure
        measurement = measure(frames, plan)
    prepared = measurement.prepared
    gauges = observation.gauge_plan(gauge_plan(system))
    coefs = prepared.components[:n_train]  # the training frames' leading principal components
    perspective = straight = None  # straight: one trajectory over the best run's state, for both checks
    extra_meta: dict = {}
    integration = None  # the steps per frame a measured path needs (steps.py)
    direct_failed = None
    if _measured_columns(prepared) and observation.applies("direct"):  # measured: fit the path itself, no encoder
        try:
            measured = prepared
            searched: list = []  # the stretch search's answer, which the pass at the settled step size reuses
            fit, perspective, straight, prepared, extra_meta = _measured_fit(measured, plan, gauges, stretch, searched)
            turned = _turned_line(measured, plan, fit)
            if turned is not None:
                other = _measured_fit(turned, plan, gauges, stretch, searched)
                if _turn_pays(fit, other[0], plan):
                    measured = turned
                    fit, perspective, straight, prepared, extra_meta = other
            first, last = extra_meta["stretch"]["start_frame"], extra_meta["stretch"]["end_frame"]
            with _threads(config.threads):
                steps = settle_substeps(system, params, fit.latents[fit.best, first:last], dt, straight,
                                        gauge=gauges, integrator=config.integrator, substeps=config.substeps)
            if steps.substeps != config.substeps:  # the steps the path needs, read by everything after
                plan = replace(plan, config=replace(config, substeps=steps.substeps))
                config = plan.config
                fit, perspective, straight, prepared, extra_meta = _measured_fit(measured, plan, gauges, stretch,
                                                                                 searched)
            integration = {**steps.to_dict(), "reason": steps.reason(config.integrator)}
        except TrainingError as exc:
            # no restart's trajectory followed the path (a learned scale that runs off, a path of
            # noise): the encoder's training is the slower, older way to the same constants
            direct_failed = str(exc)
    other_findings: list[Finding] = []
    if direct_failed is None and extra_meta:
        first, last = extra_meta["stretch"]["start_frame"], extra_meta["stretch"]["end_frame"]
        if prepared.other is not None:
            other_findings, prepared = _other_reading(prepared, plan, gauges, fit, (first, last), extra_meta)
    else:
        if direct_failed is not None:
            extra_meta = {"direct_failed": direct_failed}
        first, last = 0, n_train
        fit = _train_pass(prepared.inputs, plan, gauges, coefs, callback, progress)
        if observation.applies("perspective") and not fit.interrupted:
            straight = fit_trajectory(system, params, fit.states[fit.best, :n_train], dt, fit.records[fit.best].final,
                                      integrator=config.integrator, substeps=config.substeps)
            perspective = perspective_check(system, params, fit.states[fit.best, :n_train], dt,
                                            fit.records[fit.best].final, config, straight=straight)
            if perspective is not None and perspective["apply"]:
                reread = observation.reread(prepared, fit.states[fit.best], perspective, n_train)
                perspective["apply"] = reread is not None
                if reread is not None:
                    prepared, straight = reread, None
                    fit = _train_pass(prepared.inputs, plan, gauges, coefs, callback, progress)
    records, latents, rollouts, states = fit.records, fit.latents, fit.rollouts, fit.states
    best, selected, interrupted = fit.best, fit.selected, fit.interrupted
    span = slice(first, last)
    units = _state_units(prepared, gauges, direct_failed is None and bool(extra_meta))
    constant_unit = constant_units(system, units) if units else {}
    own_units = set() if len(units) == len(system.states) else _own_units(system, analyse(system), observation)
    estimates = {}
    for name in system.learnable:
        # restarts that read one measured path each read it in units of their own: a constant that
        # depends on the units is the best run's, not a mean over several units
        vals = np.array([records[i].value(name) for i in ([best] if name in own_units else selected)])
        unit = constant_unit.get(name) or params.get(name, ParamSpec()).unit
        estimates[name] = Estimate(float(vals.mean()), float(vals.std()) if len(vals) > 1 else 0.0, len(vals), unit)
    findings, numbers = video_checks(latents[best, span], rollouts[best, span], coefs[span], dt,
                                     records[best].score, oscillator=system.max_order >= 2,
                                     encoder=config.encoder, rank=prepared.rank, miss=records[best].miss,
                                     observation=observation)
    if prepared.caution:
        findings.append(Finding("ambiguous", prepared.caution))
    curve = getattr(observation, "curve", None)  # the brightness observation's light curve, where it chose one
    if curve is not None:
        numbers["light_curve"] = {"light": curve.light, "told": curve.told}
    mended = mended_caution(prepared.mended, first, last)
    if mended:
        findings.append(Finding("ambiguous", mended))
    findings.extend(other_findings)
    findings.extend(Finding.from_dict(f) for f in (extra_meta.get("pieces") or {}).get("findings", ()))
    if observation.applies("trajectory") and not interrupted:
        holds, numbers["whole_clip"] = whole_clip_check(system, params, states[best, span], dt,
                                                        records[best].final, config)
        if holds is not None:
            findings.append(holds)
        slow, numbers["one_trajectory"] = one_trajectory_check(system, params, states[best, span], dt,
                                                                records[best].final, config, fitted=straight)
        findings.extend(slow)
    if perspective is not None:
        numbers["perspective"] = perspective
    if integration is not None:
        numbers["integrator"] = integration
    return FitResult(
        parameters=estimates, runs=records, selected=selected, best=best,
        latent=latents[best], rollout=rollouts[best], time=np.arange(n_total) * dt, train_frames=n_train, dt=dt,
        states=list(system.states), equation=system.text, fixed=dict(system.fixed),
        settings=config.as_dict(), selection_factor=config.selection_factor,
        meta={"interrupted": interrupted, "plan": plan.to_dict(), "measured": observation.measured,
              "bends": observation.can_bend, "bend_floor": observation.bend_floor,
              "physical_units": observation.fixes_scale() or len(units) == len(system.states), "units": units,
              "length": _length_record(observation, units), "subspace": prepared.note, "rank": prepared.rank,
              "hints": [prepared.hint] if prepared.hint else [],
              "gauge": {s: g.describe() for s, g in gauges.items()}, "own_units": sorted(own_units),
              "left_out": fit.left_out, "measurement": prepared.drawing, **extra_meta},
        checks={**numbers, "findings": [f.to_dict() for f in findings]},
    )


OTHER_AGREE = 0.05  # the other reading's constants within this (relative) of the taken one's agree
OTHER_SIGMAS = 3.0  # ... or within this many of their combined standard errors


def _other_reading(prepared, plan: FitPlan, gauges, fit, stretch: tuple[int, int], meta: dict):
    """The reading the state did not take (Prepared.other: a 2-D path's position across its line
    of motion), fitted directly on the same stretch, in the same units: its constants into
    meta["measurement"]["other_reading"] and the note; a finding (ambiguous) for each constant
    that differs materially, since nothing says which reading is meant."""
    column, what = prepared.other
    system, config, dt = plan.system, plan.config, plan.dt
    x = column.reshape(-1, 1).double().cpu().numpy()
    taken = prepared.inputs.reshape(prepared.inputs.shape[0], -1)[:plan.n_train, 0].double().cpu().numpy()
    if not plan.observation.physical_units:  # in the units _measured_latent gave the taken reading
        x = _prior_units(x, plan, float(taken.std()))
        if prepared.unit_scale is not None:
            x = x * float(prepared.unit_scale[0]) * float(taken.std()) / float(plan.prior[1])
    first, last = stretch
    inits = restart_inits(system, plan.params, config.restarts, config.seed, plan.init)
    seeds = [config.seed * 1000 + i for i in range(len(inits))]
    try:
        with _threads(config.threads):
            direct = fit_path(system, plan.params, x[first:last], dt, inits, seeds, gauge=gauges,
                              integrator=config.integrator, substeps=config.substeps)
    except TrainingError:
        direct = None
    other = direct.fits[direct.best] if direct is not None else None
    mine = fit.records[fit.best].final
    errors = (meta.get("trajectory") or {}).get("errors") or {}
    record = {"reading": what, "values": None if other is None else dict(other.values)}
    drawing = dict(prepared.drawing or {})
    drawing["other_reading"] = record
    if other is None:
        note = f"; the reading {what} could not be fitted as one trajectory"
        return [], replace(prepared, note=prepared.note + note, drawing=drawing)
    differ = []
    for name in system.learnable:
        a, b = float(mine[name]), float(other.values[name])
        sigma = math.hypot(float(errors.get(name, 0.0) or 0.0), float(other.errors.get(name, 0.0) or 0.0))
        if not (math.isfinite(a) and math.isfinite(b)) or abs(a - b) > max(OTHER_AGREE * max(abs(a), abs(b)),
                                                                            OTHER_SIGMAS * sigma):
            differ.append(name)
    shown = ", ".join(f"{n} {other.values[n]:.5g} (taken: {mine[n]:.5g})" for n in system.learnable)
    note = f"; the reading {what}, fitted too, gives {shown}"
    findings = [Finding("ambiguous", f"the path read {what} gives {other.values[name]:.5g}, the reading "
                        f"taken {mine[name]:.5g} (in the same units): nothing says which is meant; name the state "
                        "for its image axis (x across; y, h, z up) or give --observe", (name,)) for name in differ]
    return findings, replace(prepared, note=prepared.note + note, drawing=drawing)


def _measured_columns(prepared) -> bool:
    """Does the observation give the state's measured columns (T, k, 1, 1), one per named state?"""
    return prepared.states is not None and prepared.inputs.dim() == 4 and tuple(prepared.inputs.shape[2:]) == (1, 1)


def _negatives(fit, plan: FitPlan) -> int:
    """How many of the best run's fitted constants are negative."""
    final = fit.records[fit.best].final
    return sum(1 for n in plan.system.learnable if n in final and final[n] < 0)


def _turned_line(prepared, plan: FitPlan, fit):
    """The prepared path read the other way along its line (observe.position.read_the_other_way),
    where which way is positive is a convention and the best fit read the first way has a negative
    constant; None otherwise."""
    if not _negatives(fit, plan):
        return None
    from .observe.position import read_the_other_way
    return read_the_other_way(prepared)


def _turn_pays(fit, turned, plan: FitPlan) -> bool:
    """Take the path read the other way where its constants have fewer negative signs and its fit
    misses the path no more than TURN_MISS times as much (the same where the equation is odd in
    the state: a sign of a constant is all that changes)."""
    here, there = fit.records[fit.best].loss, turned.records[turned.best].loss
    return _negatives(turned, plan) < _negatives(fit, plan) and math.isfinite(there) \
        and there <= TURN_MISS * here


def _measured_latent(prepared, plan: FitPlan) -> np.ndarray:
    """The measured columns as the latent (T, k): in the state's own units where the observation
    gives them, else each column at the prior's mean and spread over the training frames, as the
    encoder's latent would meet it (the gauge then maps it to the state)."""
    x = prepared.inputs.reshape(prepared.inputs.shape[0], -1).double().cpu().numpy()
    if plan.observation.physical_units:
        return x
    spread = x[:plan.n_train].std(axis=0)
    return _prior_units(x, plan, spread) * _unit_factor(prepared, plan, spread)


def _unit_factor(prepared, plan: FitPlan, spread) -> np.ndarray | float:
    """What a latent in the prior's units is multiplied by to be in the columns' own units (px, or
    m with a scale: Prepared.unit_scale), so that the path is fitted in them and its constants come
    out in px/s^2 or m/s^2; 1 where the columns have no unit. The prior's mean stays as an offset
    of that many spreads (a drain's level starts inside sqrt's domain; the gauge's offset moves it)."""
    if prepared.unit_scale is None:
        return 1.0
    return np.asarray(prepared.unit_scale, dtype=float) * np.asarray(spread, dtype=float) / float(plan.prior[1])


def _prior_units(x: np.ndarray, plan: FitPlan, spread) -> np.ndarray:
    """x (T, k) centred on its training frames' mean and set at the prior's mean and spread,
    `spread` of x counting as one prior spread."""
    mean, std = plan.prior
    return mean + std * (x - x[:plan.n_train].mean(axis=0)) / np.maximum(spread, 1e-12)


def _measured_fit(prepared, plan: FitPlan, gauges, stretch: tuple[int, int] | None = None,
                  searched: list | None = None):
    """The measured path fitted directly (train/direct.py) on its stretch (train/stretch.py), with
    the perspective re-reading where the observation has one: the _Pass the rest of fit_frames
    reads (every run reads the same latent), the perspective numbers, the best run's trajectory
    fit, the prepared columns as fitted, and the meta it adds ("stretch", "trajectory").
    searched: where the stretch search's answer (stretch, record, pieces) is kept: empty, it is
    searched and put there; filled by an earlier pass over the same path, it is reused (the pass
    at the settled step size asks again only for the constants, not where the law holds)."""
    system, params, config, observation, dt = plan.system, plan.params, plan.config, plan.observation, plan.dt
    latent = _measured_latent(prepared, plan)
    latent = latent * orientation(system, params, latent[:plan.n_train], dt,
                                  restart_inits(system, params, 1, config.seed, plan.init)[0], gauge=gauges,
                                  integrator=config.integrator, substeps=config.substeps)
    T, k = latent.shape
    options = {"integrator": config.integrator, "substeps": config.substeps}
    pieces = None
    if stretch is None:
        found = searched[0] if searched else _stretch(latent, plan, gauges, prepared.mended or ())
        if searched is not None and not searched:
            searched.append(found)
        stretch, record, pieces = found[0], copy.deepcopy(found[1]), found[2]
    else:
        record = None
    first, last = stretch
    inits = restart_inits(system, params, config.restarts, config.seed, plan.init)
    seeds = [config.seed * 1000 + i for i in range(len(inits))]
    with _threads(config.threads):
        direct = fit_path(system, params, latent[first:last], dt, inits, seeds, gauge=gauges, **options)
    records, best = direct.records, direct.best
    for rec in records:
        rec.origin = "user" if rec.index == 0 and plan.init else "equation file" if rec.index == 0 else "spread"
    good = direct.fits[best]
    if good is None:
        errors = "; ".join(f"run {r.index + 1}: {r.error}" for r in records)
        raise TrainingError(f"every run failed ({errors})")
    for r in records:
        r.miss = r.loss if math.isfinite(r.loss) else None
    selected, left_out = selection(records, config.selection_factor)
    best = min(selected, key=lambda i: records[i].loss)
    latents = np.repeat(latent[None], len(records), axis=0)
    rollouts = np.full_like(latents, np.nan)
    states = np.empty_like(latents)
    for r, fitted in zip(records, direct.fits):
        if fitted is not None:
            rollouts[r.index, first:last] = fitted_path(latent[first:last], fitted)
        s = np.array([r.gauge.get(st, {}).get("scale", 1.0) for st in system.states])
        b = np.array([r.gauge.get(st, {}).get("offset", 0.0) for st in system.states])
        states[r.index] = latent * s + b
    fit = _Pass(records, latents, rollouts, states, selected, best, False, left_out)
    straight = direct.fits[best]
    perspective = None
    if observation.applies("perspective"):
        perspective = perspective_check(system, params, states[best, first:last], dt, records[best].final, config,
                                        straight=straight)
        if perspective is not None and perspective["apply"]:
            reread = observation.reread(prepared, states[best], perspective, plan.n_train)
            perspective["apply"] = reread is not None
            if reread is not None:
                fit, _, straight, prepared, meta = _measured_fit(reread, plan, gauges, stretch)
                meta["stretch"] = record or meta["stretch"]
                if pieces is not None:
                    _joint(fit, pieces, plan, meta)
                return fit, perspective, straight, prepared, meta
    record = record or _stretch_record(stretch, plan, "as asked", "the frames asked for")
    gauge = records[best].gauge
    scale = np.array([gauge.get(st, {}).get("scale", 1.0) for st in system.states])
    offset = np.array([gauge.get(st, {}).get("offset", 0.0) for st in system.states])
    meta = {"stretch": record, "direct": True,
            # the path the estimate follows, in the equation's state units, on the stretch only (the
            # interval's bootstrap resamples it: train/interval.py), and the trajectory fitted to it
            "trajectory": {"measured": fit.states[best, first:last].tolist(),
                           "fitted": (fit.rollouts[best, first:last] * scale + offset).tolist(),
                           "mode": "segments" if last - first > 2 * SEGMENT else "whole", "frames": [first, last],
                           "misfit": straight.misfit, "values": straight.values, "errors": straight.errors,
                           "gauge": straight.gauge, "noise": record.get("noise")}}
    if pieces is not None:
        _joint(fit, pieces, plan, meta)
    return fit, perspective, straight, prepared, meta


def _joint(fit, pieces, plan: FitPlan, meta: dict) -> None:
    """Where the path has several pieces (train/pieces.py), the constants they share, fitted to all
    of them together (train/joint.py) from the best run's: every run reports them, and the path the
    interval resamples is the pieces' (meta["trajectory"]: measured, fitted, pieces); the pieces and
    their events in meta["pieces"], with what each piece alone gives."""
    system, config = plan.system, plan.config
    meta["pieces"] = pieces.to_dict(plan.dt, n_frames=plan.n_train)
    if len(pieces.spans) < 2:
        return
    best = fit.records[fit.best]
    with _threads(config.threads):
        joint = fit_pieces(system, plan.params, fit.states[fit.best], plan.dt, pieces.spans, best.final,
                           integrator=config.integrator, substeps=config.substeps)
    if joint is None:
        meta["pieces"]["joint"] = None
        return
    for r in fit.records:
        r.final = {**r.final, **joint.values}
        r.aligned = {}
    # every piece's trajectory drawn and kept, in the latent's units (the state is s * latent + b)
    scale = np.array([best.gauge.get(st, {}).get("scale", 1.0) for st in system.states])
    offset = np.array([best.gauge.get(st, {}).get("offset", 0.0) for st in system.states])
    done = 0
    for a, b in pieces.spans:
        fit.rollouts[:, a:b] = (joint.fitted[done:done + b - a] - offset) / scale
        done += b - a
    meta["pieces"]["joint"] = joint.to_dict()
    meta["pieces"]["findings"] = [f.to_dict() for f in disagreement(joint, pieces.spans, plan.dt)]
    meta["trajectory"].update(
        measured=np.concatenate([fit.states[fit.best, a:b] for a, b in pieces.spans]).tolist(),
        fitted=joint.fitted.tolist(), pieces=[b - a for a, b in pieces.spans], misfit=joint.misfit,
        values=joint.values, errors=joint.errors, frames=[pieces.spans[0][0], pieces.spans[-1][1]],
        scatter=joint.scatter)


def _stretch(latent: np.ndarray, plan: FitPlan, gauges,
             mended: Sequence[int] = ()) -> tuple[tuple[int, int], dict | None, Pieces | None]:
    """The stretch of the training frames the runs fit and its record (contract: meta["stretch"]);
    with pieces, the pieces (train/pieces.py) and the stretch is the longest of them. mended: the
    frames the reader read from their neighbours."""
    n = plan.n_train
    if not plan.config.stretch or n < 3 * MIN_SEED:
        return (0, n), None, None
    if not plan.observation.applies("stretch"):
        return (0, n), _stretch_record((0, n), plan, "the whole clip", plan.observation.no_stretch), None
    system, params, config = plan.system, plan.params, plan.config
    warm = dict(restart_inits(system, params, 1, config.seed, plan.init)[0])
    x = latent[:n]
    with _threads(config.threads):
        if plan.observation.physical_units:
            # a zero the fit refines (the angle's, observe.angle) is one for the whole clip: free in each
            # stretch the search tries, a hold is a swing at rest about a shifted zero (a held pendulum's
            # 1.8 s at 43 degrees joined its swing as "one trajectory", and the fit of both failed); held
            # as read, a zero read 0.68 degrees off (a swing of 56 degrees) left no two swings one trajectory
            x = _zeroed(x, plan, gauges, warm)
            gauges = {s: replace(g, offset_learned=False) for s, g in gauges.items()}
        first = screen(system, params, x, plan.dt, warm, gauge=gauges,
                       integrator=config.integrator, substeps=config.substeps)
    if first is not None:
        first = off_bounds(first, warm, params)
        warm.update({k: first.values[k] for k in system.learnable})

    def fit(a: int, b: int):
        # few iterations from the windows' constants, a learned scale held at theirs: the search
        # asks whether frames fit, many times, not for the last digit
        got = (full_fit(system, params, x[a:b], plan.dt, first, gauge=gauges, iterations=STRETCH_ITERATIONS,
                        integrator=config.integrator, substeps=config.substeps, **long_options(b - a))
               if first is not None else
               fit_trajectory(system, params, x[a:b], plan.dt, warm, gauge=gauges, iterations=STRETCH_ITERATIONS,
                              integrator=config.integrator, substeps=config.substeps, **long_options(b - a)))
        # every fit starts from the same place: a short seed's constants (a decay's level, barely
        # determined over a few frames) sent the next fit of the whole clip into a far basin
        return None if got is None else got.residuals
    pieces = None
    with _threads(config.threads):
        if config.pieces == "one":
            found = find_stretch(x, plan.dt, fit)
        else:
            unread = np.zeros(n, dtype=bool)
            unread[[i for i in mended if i < n]] = True
            track = getattr(plan.observation, "track", None)
            unseen = np.isnan(track.xy[:n, 0]) if track is not None and len(track) >= n else None
            pieces = find_pieces(x, plan.dt, fit, unread=unread, unseen=unseen,
                                 enters=bool(getattr(track, "enters", False)),
                                 leaves=bool(getattr(track, "leaves", False)) and len(track) <= n)
            if len(pieces.spans) > 1 and plan.observation.measured:
                pieces = _same_motion(latent[:n], pieces, plan, warm)
            found = _longest(latent[:n], pieces, plan.dt) if pieces.spans else find_stretch(x, plan.dt, fit)
            if not pieces.spans:
                pieces = None
    record = found.to_dict(plan.dt)
    record["noise"] = found.noise
    if found.start == 0 and found.end == n:
        record["reason"] = "one trajectory of the equation explains the whole clip"
    return (found.start, found.end), record, pieces


def _zeroed(x: np.ndarray, plan: FitPlan, gauges, start: Mapping[str, float]) -> np.ndarray:
    """x (T, k) with each state whose zero the fit refines (gauges' offset_learned; its scale as
    read) shifted to the zero one trajectory of the frames that move finds (a screen, then a whole
    fit from it; stretch.at_rest: a hold or a rest at either end of the clip is left out, so it
    cannot pull the zero to its own place): the path the stretch search asks about, with that zero
    held. x as it is where the fits fail, or put the zero beyond half the moving path's range."""
    states = plan.system.states
    columns = [i for i, s in enumerate(states) if gauges.get(s) is not None and gauges[s].offset_learned
               and not gauges[s].scale_learned]
    if not columns:
        return x
    path = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    moving = np.flatnonzero(~at_rest(path, plan.dt, noise_level(path)))
    if len(moving) < 3 * MIN_SEED:
        return x
    lo, hi = int(moving[0]), int(moving[-1]) + 1
    options = dict(integrator=plan.config.integrator, substeps=plan.config.substeps)
    lead = screen(plan.system, plan.params, path[lo:hi], plan.dt, start, gauge=gauges, **options)
    if lead is not None:
        # the windows' zero is rough (a swing of 56 degrees: 1.5 degrees for 0.68): one trajectory's
        lead = full_fit(plan.system, plan.params, path[lo:hi], plan.dt, lead, gauge=gauges, **options,
                        **long_options(hi - lo)) or lead
    if lead is None or not lead.gauge:
        return x
    out = path.copy()
    for i in columns:
        b = float((lead.gauge.get(states[i]) or {}).get("offset", math.nan))
        if math.isfinite(b) and abs(b) <= 0.5 * float(np.ptp(path[lo:hi, i])):
            out[:, i] += b
    return out.reshape(np.shape(x))


def _same_motion(x: np.ndarray, pieces: Pieces, plan: FitPlan, start: Mapping[str, float]) -> Pieces:
    """The pieces less those whose own constants are another motion's (joint.other_motions: a
    ball rolling on the floor after its bounces, then a hand): a measured path's pieces, fitted
    each alone from the windows' constants, before the runs choose their stretch among them."""
    config = plan.config
    joint = fit_pieces(plan.system, plan.params, x, plan.dt, pieces.spans, start,
                       integrator=config.integrator, substeps=config.substeps)
    if joint is None:
        return pieces
    drop = other_motions(joint, released=any(e.kind == "release" for e in pieces.events))
    return pieces.without(drop) if drop else pieces


def _longest(x: np.ndarray, pieces: Pieces, dt: float) -> Stretch:
    """The piece that travels farthest, as a stretch (the runs are fitted on it first)."""
    a, b = max(pieces.spans, key=lambda s: float(np.ptp(x[s[0]:s[1]], axis=0).max()))
    at = {e.frame: e.kind for e in pieces.events}
    ends = {"stop": f"the motion stops at {b * dt:.3g} s"}
    why_start = (f"the object enters the view, from {a * dt:.3g} s" if at.get(a) == "enter" else
                 "from the clip's first frame" if a == 0 else
                 f"the motion starts at {a * dt:.3g} s (released: held before)" if at.get(a) == "release" else
                 f"after a bounce, from {a * dt:.3g} s" if a != pieces.spans[0][0] else
                 f"before {a * dt:.3g} s the path does not follow one trajectory of the equation")
    bounce = next((e for e in pieces.events if e.kind == "bounce" and e.frame >= b - 2), None)
    why_end = (f"the object leaves the view at {b * dt:.3g} s" if at.get(b) == "gone" else
               "to the clip's last frame" if b >= len(x) else ends["stop"] if at.get(b) == "stop" else
               f"a bounce at {bounce.frame * dt:.3g} s" if bounce is not None and bounce.frame <= b + 3 else
               f"from {b * dt:.3g} s the path leaves one trajectory of the equation")
    return Stretch(a, b, why_start, why_end, pieces.noise)


def _stretch_record(stretch: tuple[int, int], plan: FitPlan, source: str, reason: str) -> dict:
    first, last = stretch
    return {"start_frame": first, "end_frame": last, "start_s": first * plan.dt, "end_s": last * plan.dt,
            "reason": reason, "source": source}


def _state_units(prepared, gauges, fitted_directly: bool) -> dict[str, str]:
    """state -> the unit its measured path was fitted in (px, or m with a scale), for the states
    whose scale the gauge does not learn (a learned scale puts the state in units of its own);
    {} where the path was not fitted directly (an encoder's latent is in the prior's units)."""
    if not fitted_directly or prepared.units is None or prepared.states is None:
        return {}
    return {s: u for s, u in zip(prepared.states, prepared.units) if not gauges[s].scale_learned}


def _length_record(observation: ObservationModel, units: Mapping[str, str]) -> dict | None:
    """How lengths were read (meta["length"]): the unit, the source pixels per frame pixel and,
    with a scale stick, the metres per source pixel and its relative standard deviation."""
    if not units:
        return None
    lengths = observation.lengths
    return {"unit": lengths.unit, "frame_scale": list(lengths.frame_scale), "metres_per_px": lengths.metres_per_px,
            "relative_std": lengths.relative_std}


def _own_units(system: OdeSystem, analysis, observation: ObservationModel) -> set[str]:
    """The constants whose restarts are not comparable: with a measured latent every restart
    reads the same path, scaled and shifted in its own way, and a constant whose value depends on
    the latent's scale differs between them by that alone; none where the latent is the state in
    its own units (every restart reads the same numbers)."""
    if not observation.measured or observation.fixes_scale():
        return set()
    return {n for n in system.learnable if analysis[n].scale == "dependent"}


@dataclass
class _Pass:
    """One training of every restart on one reading of the frames, its runs selected."""

    records: list[RunRecord]
    latents: np.ndarray
    rollouts: np.ndarray
    states: np.ndarray
    selected: list[int]
    best: int
    interrupted: bool
    left_out: dict[int, str]  # run index -> why it was left out of the estimate (fitode.train.selection)


def _train_pass(frames: torch.Tensor, plan: FitPlan, gauges, coefs: np.ndarray, callback: Callback | None,
                progress: bool) -> _Pass:
    """Every restart trained on the encoder's inputs `frames` (their first plan.n_train), each run's
    latent, rollout and state on every frame, and the runs selected for the estimate."""
    system, params, config, observation, dt = plan.system, plan.params, plan.config, plan.observation, plan.dt
    n_train, init = plan.n_train, plan.init
    inits = restart_inits(system, params, config.restarts, config.seed, init)
    origins = ["user" if init else "equation file"] + ["spread"] * (len(inits) - 1)
    seeds = [config.seed * 1000 + i for i in range(len(inits))]
    targets: dict[int, np.ndarray] = {}
    with _threads(config.threads), interrupts.deferred_signals():
        n_data = min(DATA_STARTS, len(inits) - 1)
        if n_data:
            candidates = restart_inits(system, params, CANDIDATES, config.seed + 1, None)[1:] + inits[:1]
            period = dominant_period(coefs, dt) if system.max_order >= 2 else None
            found = data_starts(coefs, dt, system, params, config, gauges, candidates, n_data, period=period)
            for i, start in enumerate(found, start=1):
                inits[i], origins[i], targets[i] = start.constants, "data", start.latent
        trained = train_restarts(frames[:n_train], dt, system, params, config, inits, seeds=seeds,
                                 observation=observation, plan=gauges, callback=callback, progress=progress,
                                 targets=targets)
        latents, rollouts, states = _trajectories(trained, frames, dt)
        late = interrupts.pending()  # a signal after the last step: the fit finished, but the user asked to stop
    records = trained.records
    for rec, origin in zip(records, origins):
        rec.origin = origin
    for r in records:
        if r.status != "failed":
            if observation.applies("score"):
                r.score = separation_score(latents[r.index, :n_train], coefs, exclude=SCORE_EXCLUDE)
            var = float(np.var(latents[r.index, :n_train], axis=0).sum())
            r.miss = r.history.mse[-1] / var if r.history.mse and var > 0 else None
    interrupted = late or any(r.status == "interrupted" for r in records)
    selected, left_out = selection(records, config.selection_factor)
    if not selected and interrupted:
        selected, left_out = selection(records, config.selection_factor, statuses=("ok", "interrupted"))
        if not selected:
            raise KeyboardInterrupt
    if not selected:
        errors = "; ".join(f"run {r.index + 1}: {r.error}" for r in records)
        raise TrainingError(f"every run failed ({errors})")
    best = min(selected, key=lambda i: records[i].loss)
    _align(records, latents[:, :n_train], best,
           lambda columns: sign_odd(system, [system.states[j] for j in columns]), per_column=observation.measured)
    return _Pass(records, latents, rollouts, states, selected, best, interrupted, left_out)


def _align(records: list[RunRecord], latents: np.ndarray, best: int,
           odd: set[str] | Callable[[frozenset[int]], set[str]], per_column: bool = False) -> None:
    """Each run's values in the best run's orientation. Where a run's latent runs opposite to the
    best run's, the constants that change sign with the state are negated: for a one-dimensional
    latent, or (per_column: each latent dimension is one measured state) per dimension, each
    state flipped on its own. odd: the constants that change sign when every state does, or a
    function from the flipped latent dimensions to the constants that change sign with them."""
    d = latents.shape[2]
    ref = latents[best] - latents[best].mean(axis=0)
    for r in records:
        flipped: frozenset[int] = frozenset()
        if (d == 1 or per_column) and r.final and np.all(np.isfinite(latents[r.index])):
            z = latents[r.index] - latents[r.index].mean(axis=0)
            flipped = frozenset(j for j in range(d) if float(z[:, j] @ ref[:, j]) < 0)
        names: set[str] = set()
        if flipped:
            names = (odd if flipped == frozenset(range(d)) else set()) if isinstance(odd, set) else odd(flipped)
        r.aligned = {n: (-v if n in names else v) for n, v in r.final.items()}




@torch.no_grad()
def _trajectories(trained: Trained, frames: torch.Tensor, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every restart's latent for every frame (R, T, d), its physics rollout from the first
    frames (in latent units; NaN where a long extrapolation leaves the equation's domain), and
    its latent as the equation's state (the gauge applied)."""
    encoder, block, gauge = trained.encoder, trained.block, trained.gauge
    encoder.eval()
    latent = encode_all(encoder, frames)
    head = gauge.to_state(latent[:, None, : block.n_context])
    rollout = gauge.to_latent(block(head, frames.shape[0], dt)[:, 0])
    states = gauge.to_state(latent[:, None])[:, 0]
    return latent.cpu().double().numpy(), rollout.cpu().double().numpy(), states.cpu().double().numpy()
