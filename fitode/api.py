"""The three steps `fitode.fit` (fitode.fitting) is made of.

    request(...)                 every check that needs no frames (the equation, the options,
                                 the calibration text): a FitRequest
    plan(request, frames, dt)    every choice resolved once on the frames: a FitPlan
    execute(request, plan, ...)  training, the calibration when asked, the assessment: a FitResult

`fit` runs the three; the command line runs them apart, so that a typo costs no video decode and
the header it prints before training is the plan itself.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np

from fitode.eqparse import OdeSystem, ParamSpec
from fitode.errors import ConfigError, FitodeError
from fitode.train.config import TrainConfig

if TYPE_CHECKING:  # torch comes with the plan: a request that fails (an equation, a video) costs no torch import
    import torch

    from fitode.train.observe import ObservationModel
    from fitode.train.plan import FitPlan
    from fitode.train.result import FitResult
    from fitode.train.trainer import Callback


@dataclass(frozen=True)
class FitRequest:
    """What the user asked for, checked, before any frame is seen.

    spec: the equation file's EquationSpec (None for equation text or an OdeSystem). observe:
    a model name, an instance or None (auto); observe_source says where a name came from.
    calibration: parsed --calibrate points (fitode.calibrate.CalibrationPoint), empty for none.
    """

    system: OdeSystem
    params: Mapping[str, ParamSpec]
    config: TrainConfig
    init: Mapping[str, float] | None = None
    train_fraction: float = 1.0
    observe: str | ObservationModel | None = None
    observe_source: str = "as asked"
    calibration: tuple = ()
    spec: Any = None
    equation: str | None = None  # the equation as the user typed it, where it is one of several candidates
    scale: Any = None  # a scale stick (fitode.scale.ScaleStick): lengths in metres; None: in source pixels


def request(*, eq: str | None = None, system: str | OdeSystem | None = None, eq_file: str | None = None,
            const: Mapping[str, float] | None = None, free: Iterable[str] = (),
            init: Mapping[str, float] | None = None, params: Mapping[str, ParamSpec] | None = None,
            prior: tuple[float, float] | None = None, train_fraction: float = 1.0,
            observe: str | ObservationModel | None = None, calibrate: str | None = None,
            scale=None, candidate: int | None = None, **options) -> FitRequest:
    """Every check of a fit request that needs no frames, in one place (the API, the pipeline and
    batch all come through here): the equation, the training options, the prior, init's names,
    train_fraction, the observation's name and the calibration's text. candidate: which of several
    candidate equations (a list as eq, or an equation file's alternatives: see requests)."""
    if isinstance(eq, (list, tuple)) and len(eq) > 1 and candidate is None:
        raise ConfigError(f"{len(eq)} equations: compare them with fitode.api.requests and fitode.compare "
                          "(fitode.fit and `fitode VIDEO --eq A --eq B` do)")
    ode, spec_params, spec_prior, spec_observe, spec = _equation(eq, system, eq_file, const, free, candidate)
    if params is not None:
        spec_params = {**spec_params, **params}
    if "prior" in options:
        raise ConfigError("give the prior as prior=(mean, std), not as a training option")
    config = TrainConfig.from_options(options, prior=tuple(prior) if prior is not None else tuple(spec_prior))
    if not ode.learnable:
        raise FitodeError(_nothing_to_learn(ode))
    _check_init(ode, init, spec_params)
    if isinstance(train_fraction, bool) or not isinstance(train_fraction, (int, float)) or not 0 < train_fraction <= 1:
        raise ConfigError(f"train_fraction must be in (0, 1], got {train_fraction!r}")
    if config.device.startswith("cuda"):
        _check_cuda(config.device)
    source = "as asked"
    if observe is None and spec_observe not in (None, "auto"):
        observe, source = spec_observe, "from the equation file"
    if isinstance(observe, (str, Mapping)):  # a name, or one per state
        from fitode.train.observe.catalog import check_states, parse_observe
        observe = parse_observe(observe)
        check_states(observe, ode.states)
    points: tuple = ()
    if calibrate is not None:
        from fitode.calibrate import parse_calibration
        points = tuple(parse_calibration(calibrate, ode.states))
    stick = None
    if scale is not None:
        from fitode.scale import parse_scale
        stick = parse_scale(scale)
    return FitRequest(system=ode, params=dict(spec_params), config=config, init=dict(init) if init else None,
                      train_fraction=float(train_fraction), observe=observe, observe_source=source,
                      calibration=points, spec=spec, scale=stick)


def _check_cuda(device: str) -> None:
    import torch
    if not torch.cuda.is_available():
        raise ConfigError(f"device {device}: no CUDA device is available here (torch {torch.__version__}, "
                          f"built {'with' if torch.version.cuda else 'without'} CUDA); use cpu")


def plan(req: FitRequest, frames: torch.Tensor, dt: float, track=None, geometry=None) -> FitPlan:
    """Every choice of the fit resolved on its frames (float (T, C, H, W), as_frames), the
    reader's track of them (fitode.train.observe.track.Track, or None) and where they lie in the
    source (fitode.measurement.FrameGeometry, or None: frames given as they are, their pixels the
    source's), which with the request's scale stick says how a measured length reads."""
    from fitode.train.observe.base import Lengths
    from fitode.train.plan import make_plan

    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating)) or not (dt > 0 and np.isfinite(dt)):
        raise ConfigError(f"dt must be a positive number of seconds, got {dt!r}")
    n_train = max(int(round(req.train_fraction * frames.shape[0])), 1)
    stick = req.scale
    if stick is not None and geometry is not None:
        stick.check_inside(geometry.source_size)
    lengths = Lengths(geometry.scale if geometry is not None else (1.0, 1.0),
                      stick.metres_per_px if stick is not None else None,
                      stick.relative_std if stick is not None else 0.0)
    return make_plan(req.system, req.params, frames, float(dt), req.config, observe=req.observe, n_train=n_train,
                     init=req.init, observe_source=req.observe_source, track=track, lengths=lengths)


def measure(fit_plan: FitPlan, frames: torch.Tensor):
    """The measurement stage (fitode.train.measure.measure): what the plan's observation reads off
    the frames, or its one-line error, before any fit or output."""
    from fitode.train.measure import measure as measure_frames
    return measure_frames(frames, fit_plan)


def execute(req: FitRequest, fit_plan: FitPlan, frames: torch.Tensor, *, time_offset: float = 0.0,
            callback: Callback | None = None, progress: bool = False, rate_std: float = 0.0,
            stretch: tuple[int, int] | None = None, measurement=None) -> FitResult:
    """Train the plan, calibrate when asked (not after an interruption: unfinished training gives
    no latent worth a scale), make every constant's interval and assess: the FitResult with its
    intervals, verdicts and warnings. rate_std: the relative uncertainty of the frame rate (0 for
    a dt or --fps the user gave; fitode.train.interval.RATE_CONTAINER_STD for a container's).
    stretch: the frames a measured path is fitted on, as fitode.train.trainer.fit_frames takes it;
    measurement: the plan's Measurement (fitode.train.measure), made by `measure` before."""
    from fitode.numeric_warnings import kept

    with kept() as numeric:  # numpy's overflow warnings become the result's warnings, not terminal noise
        result = _execute(req, fit_plan, frames, time_offset=time_offset, callback=callback, progress=progress,
                          rate_std=rate_std, stretch=stretch, measurement=measurement)
    result.warnings += numeric.lines()
    return result


def _execute(req: FitRequest, fit_plan: FitPlan, frames: torch.Tensor, *, time_offset: float,
             callback: Callback | None, progress: bool, rate_std: float,
             stretch: tuple[int, int] | None, measurement) -> FitResult:
    from fitode.eqparse import analyse
    from fitode.interrupted import fitted, stage
    from fitode.train.assess import assess
    from fitode.train.trainer import fit_frames

    # an interruption after training keeps the estimates: fitode.interrupted.Stopped carries them
    calibrating = bool(req.calibration)
    result = fitted(fit_frames, frames, fit_plan, callback=callback, progress=progress, stretch=stretch,
                    calibrating=calibrating, measurement=measurement)
    try:
        analysis = analyse(req.system)
    except Exception:  # noqa: BLE001 - the analysis is advice; sympy can fail on unusual equations
        analysis = None
    calibrated, extra = (), []
    if req.calibration and not result.meta.get("interrupted"):
        with stage(result, "calibration", calibrating=calibrating):
            calibrated, extra = _calibrate(result, req, analysis, time_offset)
    elif req.calibration:
        result.meta["calibration_skipped"] = "interrupted"
    with stage(result, "intervals"):
        _intervals(result, req, rate_std)
    with stage(result, "assessment"):
        assess(result, analysis, calibrated=calibrated, extra=extra).apply(result)
    # the parser's and the measurement's advice on what the user said stays with the numbers it concerns
    result.warnings[:0] = list(req.system.hints) + list(result.meta.get("hints", ()))
    from fitode.objects import naming_line
    other = naming_line(result, fit_plan)  # the tracker's strongest change is not always the equation's object
    if other:
        result.warnings.append(other)
    return result


def _intervals(result: FitResult, req: FitRequest, rate_std: float) -> None:
    """Each constant's 95% interval (fitode.train.interval) into its Estimate, and how it was
    made into result.checks["interval"] (None where none could be made)."""
    from fitode.train.interval import result_intervals

    constants = (result.calibration or {}).get("constants", {})
    relative = {n: float(c.get("relative_std", 0.0)) for n, c in constants.items() if c.get("converted")}
    for name, share in _scale_shares(result, req.system).items():
        relative[name] = math.hypot(relative.get(name, 0.0), share)
    intervals, boot = result_intervals(result, req.system, req.params, rate_std=rate_std, calibration=relative,
                                       seed=req.config.seed)
    for name, iv in intervals.items():
        result.parameters[name].interval = [iv.low, iv.high]
    result.checks["interval"] = None if boot is None else {
        **boot.to_dict(), "rate_std": rate_std, "shares": {n: iv.shares for n, iv in intervals.items()}}


def _scale_shares(result: FitResult, system: OdeSystem) -> dict[str, float]:
    """The relative standard deviation each constant takes from the scale stick's: a constant that
    goes as length**p (g: p = 1, k in h' = -k*sqrt(h): p = 1/2) takes p times the stick's."""
    length = result.meta.get("length") or {}
    rel = float(length.get("relative_std") or 0.0)
    units = result.meta.get("units") or {}
    if not rel or not units:
        return {}
    from fitode.eqparse.identify import scale_exponents

    out = {}
    for name, powers in scale_exponents(system).items():
        if powers is not None:
            p = sum(v for s, v in powers.items() if s in units)
            if p:
                out[name] = abs(p) * rel
    return out


def _calibrate(result: FitResult, req: FitRequest, analysis, time_offset: float):
    """Apply the calibration to the result in place: values of the converted constants in
    physical units (their latent values kept beside them) and the calibrated trajectories."""
    from fitode.calibrate import calibrate_result
    from fitode.report import analysis_dict

    cal = calibrate_result(result, req.system, req.params, list(req.calibration), analysis_dict(analysis),
                           time_offset=time_offset, seed=req.config.seed)
    for name, c in cal.constants.items():
        if c["converted"]:
            est = result.parameters[name]
            est.latent_value, est.value, est.std, est.calibrated = est.value, c["after"], c["std_after"], True
            if c.get("gauge_fixed"):  # one fit of the calibrated path, not a mean over restarts
                est.std, est.n_runs = 0.0, 1
            # in the units of --calibrate: the equation file's unit, not the measured path's px
            spec = req.params.get(name)
            est.unit = spec.unit if spec is not None else None
    result.calibration = {**cal.to_dict(), "lines": cal.lines(), "latent": cal.latent.tolist(),
                          "rollout": cal.rollout.tolist(), "time_offset": time_offset,
                          "ylabels": cal.ylabels(result.states), "gauge_fixed": cal.gauge_fixed_names()}
    return cal.converted_names(), cal.findings(req.params)


def _nothing_to_learn(ode) -> str:
    """The one line for an equation whose every constant is fixed, with how to estimate one: a
    known constant (g) is fixed at its value unless freed, and a user who writes y'' = -g for a
    fall wants g measured more often than not."""
    from fitode.eqparse import KNOWN_CONSTANTS

    known = [n for n in ode.fixed if n in KNOWN_CONSTANTS and ode.fixed[n] == KNOWN_CONSTANTS[n]]
    if not ode.fixed:
        return "the equation has no constant to estimate: write one into it (y'' = -g, x'' = -k*x)"
    if known:
        n = known[0]
        return (f"the equation has no constant to estimate: {n} is the known {KNOWN_CONSTANTS[n]:g}, fixed unless freed; "
                f"--free {n} (fitode.fit(..., free=['{n}'])) estimates it")
    return (f"the equation has no constant to estimate: every name is fixed ({', '.join(sorted(ode.fixed))}, by --const "
            "or the equation file); leave one unfixed to estimate it")


def _check_init(ode: OdeSystem, init: Mapping[str, float] | None, params: Mapping[str, ParamSpec]) -> None:
    unknown = sorted(set(init or {}) - set(ode.learnable))
    if unknown:
        raise ConfigError(f"init names {', '.join(unknown)}, which is not a learnable constant "
                          f"(learnable: {', '.join(ode.learnable)})")
    for name, v in (init or {}).items():
        spec = params.get(name) if params else None
        lo, hi = (spec.min, spec.max) if spec is not None else (None, None)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or (lo is not None and not v > lo) or (hi is not None and not v < hi):
            raise ConfigError(f"init {name}={v!r} must be a number strictly inside its bounds "
                              f"({'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'})")


def as_frames(frames) -> torch.Tensor:
    """Any common frame layout -> float32 (T, C, H, W)."""
    import torch

    x = torch.as_tensor(np.asarray(frames) if not isinstance(frames, torch.Tensor) else frames)
    x = x.detach().to(torch.float32)
    if x.ndim == 3:
        x = x[:, None]
    elif x.ndim == 4 and x.shape[-1] in (1, 3) and x.shape[1] not in (1, 3):
        x = x.permute(0, 3, 1, 2)
    if x.ndim != 4:
        raise FitodeError(f"frames must be (T, H, W) or (T, C, H, W), got shape {tuple(x.shape)}")
    if x.shape[0] < 2:
        raise FitodeError("need at least two frames")
    if not torch.isfinite(x).all():
        raise FitodeError("frames contain NaN or infinite values")
    return x.contiguous()


def requests(*, eq: str | Sequence[str] | None = None, system: str | OdeSystem | None = None,
             eq_file: str | None = None, const: Mapping[str, float] | None = None, free: Iterable[str] = (),
             **rest) -> list[FitRequest]:
    """One FitRequest per candidate equation (request's keywords): each text of a list given as
    eq, or an equation file's `equation` and `alternatives`; a single one where there is one
    equation. const and free apply to each candidate where it has the name (each must be some
    candidate's); init names the constants of the first candidate. Several candidates must have
    as many states (matched in order) as they are fitted on one measured path."""
    from fitode.eqfile import candidate_texts, constant_names
    from fitode.names import parse_names

    texts = [] if isinstance(system, OdeSystem) else candidate_texts(eq, eq_file, system)
    if len(texts) <= 1:
        one = eq[0] if isinstance(eq, (list, tuple)) and eq else eq
        return [request(eq=one, system=system, eq_file=eq_file, const=const, free=free, **rest)]
    const, free = dict(const or {}), parse_names(list(free or ()))
    out = [request(eq=eq, system=system, eq_file=eq_file, const=const, free=free, candidate=i,
                   **(rest if i == 0 else {k: v for k, v in rest.items() if k != "init"}))
           for i in range(len(texts))]
    names = set().union(*(set(r.system.learnable) | set(r.system.fixed) for r in out))
    missing = sorted((set(const) | set(free)) - names)
    if missing:
        raise ConfigError(f"{', '.join(missing)}: no candidate equation has a constant of that name")
    first = out[0].system
    for text, r in zip(texts[1:], out[1:]):
        if len(r.system.states) != len(first.states):
            raise ConfigError(f"the candidates must describe the same measured states to be compared on one path: "
                              f"{texts[0]!r} has {len(first.states)} ({', '.join(first.states)}), {text!r} has "
                              f"{len(r.system.states)} ({', '.join(r.system.states)})")
    return [replace(r, equation=t) for r, t in zip(out, texts)]


def _equation(eq, system, eq_file, const, free, candidate=None):
    """The system, its parameters, prior, observation model (None: auto) and the equation file's
    spec (None for text or an OdeSystem) from the equation given (candidate: which of several)."""
    if isinstance(system, OdeSystem):
        if eq is not None or eq_file is not None:
            raise FitodeError("give the equation once: eq, system or eq_file")
        return system, {}, (0.0, 1.0), None, None
    from fitode.eqfile import resolve
    ode, spec = resolve(eq=eq, eq_file=eq_file, system=system, const=dict(const or {}), free=tuple(free or ()),
                        candidate=candidate)
    if spec is None:
        return ode, {}, (0.0, 1.0), None, None
    return ode, dict(spec.parameters), (spec.prior_mean, spec.prior_std), spec.observe, spec
