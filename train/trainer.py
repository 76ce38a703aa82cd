"""The trainer: learn an encoder and the equation's constants together, with restarts.

One run: Adam on the encoder (its own learning rate) and on each learnable constant (its own
group, at the scale the physics block reports). Every step encodes each distinct frame of the
batch once, gathers the windows, rolls the physics out from each window's first frames and
minimises prediction error plus the KL term. A run stops when the constants and the loss have
stopped moving, or at max_steps; a run whose loss or constants turn non-finite stops at once
and is reported as failed.
"""
from __future__ import annotations

import math
import os
import signal
import time
from dataclasses import asdict, dataclass, field
from typing import Callable, Mapping

import numpy as np
import torch

from fitode.codegen import PhysicsBlock
from fitode.eqparse import FitodeError, OdeSystem, ParamSpec
from fitode.errors import TrainingError

from .encoders import make_encoder
from .loss import latent_loss
from .result import Estimate, FitResult, RunRecord
from .windows import Windows, distinct_frames


@dataclass
class TrainConfig:
    window: int = 20
    max_steps: int = 2000
    min_steps: int = 200
    lr: float = 1e-4
    const_lr: float = 0.05
    batch_windows: int | None = None
    use_kl: bool = True
    prior: tuple[float, float] = (0.0, 1.0)
    integrator: str = "rk4"
    substeps: int = 1
    init_mode: str = "difference"
    encoder: str = "mlp"
    tol: float = 1e-3
    patience: int = 100
    horizon_warmup: int = 200
    settle_factor: float = 0.1
    selection_factor: float = 1.5
    restarts: int = 3
    workers: int = 1
    seed: int = 0
    device: str = "cpu"


@dataclass
class StepInfo:
    """What a callback sees after every optimisation step."""

    run: int
    step: int
    loss: float
    mse: float
    kl: float
    constants: dict[str, float]


Callback = Callable[[StepInfo], object]


def restart_inits(system: OdeSystem, params: Mapping[str, ParamSpec], n: int, seed: int,
                  fixed_init: Mapping[str, float] | None = None) -> list[dict[str, float]]:
    """Initial constants for n restarts, spread as in the paper.

    Run 0 starts from the equation file's init (1.0 when none); the others from seeded draws:
    uniform in [-10, 10] for an unbounded constant, log-uniform over three decades around the
    init for a positive one, uniform inside two bounds. A value in fixed_init is used by every run.
    """
    rng = np.random.default_rng(seed)
    inits: list[dict[str, float]] = []
    for i in range(n):
        row = {}
        for name in system.learnable:
            spec = params.get(name, ParamSpec())
            base = spec.init if spec.init is not None else _default_init(spec)
            if fixed_init and name in fixed_init:
                row[name] = float(fixed_init[name])
            elif i == 0:
                row[name] = float(base)
            elif spec.min is not None and spec.max is not None:
                row[name] = float(rng.uniform(spec.min, spec.max))
            elif spec.min is not None or spec.max is not None:
                edge = spec.min if spec.min is not None else spec.max
                sign = 1.0 if spec.min is not None else -1.0
                gap = abs(base - edge) or 1.0
                row[name] = float(edge + sign * gap * 10 ** rng.uniform(-1.5, 1.5))
            else:
                row[name] = float(rng.uniform(-10.0, 10.0))
        inits.append(row)
    return inits


def _default_init(spec: ParamSpec) -> float:
    if spec.min is not None and spec.max is not None:
        return 0.5 * (spec.min + spec.max)
    if spec.min is not None:
        return spec.min + 1.0
    if spec.max is not None:
        return spec.max - 1.0
    return 1.0


@dataclass
class _Run:
    record: RunRecord
    encoder: torch.nn.Module | None = None
    block: PhysicsBlock | None = None


def train_run(frames: torch.Tensor, dt: float, system: OdeSystem, params: Mapping[str, ParamSpec],
              config: TrainConfig, init: Mapping[str, float], *, index: int = 0, seed: int = 0,
              callback: Callback | None = None, progress: bool = False) -> _Run:
    """One restart on normalised frames (T, C, H, W) already on the target device."""
    torch.manual_seed(seed)
    t0 = time.perf_counter()
    n_frames = frames.shape[0]
    windows = Windows(n_frames, config.window)
    encoder = make_encoder(config.encoder, tuple(frames.shape[1:]), system.dim).to(frames.device)
    block = PhysicsBlock(system, params, integrator=config.integrator, substeps=config.substeps,
                         init=config.init_mode, n_windows=windows.count).to(frames.device)
    block.set_constants(init)
    nc = block.n_context
    first = getattr(block, "anchor", nc - 1) + 1  # first frame that is a prediction, not an input
    if config.window <= nc:
        raise TrainingError(f"window of {config.window} frames is too short for an equation that needs {nc} to start")
    groups = [{"params": list(encoder.parameters()), "lr": config.lr, "name": "encoder"}]
    groups += block.param_groups(lr=config.const_lr)
    other = [p for n, p in block.named_parameters() if all(p is not q for g in groups for q in g["params"])]
    if other:  # learnable per-window initial derivatives
        groups.append({"params": other, "lr": config.lr * 10, "name": "initial-derivatives"})
    opt = torch.optim.Adam(groups)
    base_lrs = [g["lr"] for g in opt.param_groups]

    names = list(system.learnable)
    hist: dict = {"step": [], "loss": [], "mse": [], "kl": [], "constants": {n: [] for n in names}}
    record = RunRecord(index=index, seed=seed, init=dict(init), final={}, loss=math.inf, steps=0, status="ok")
    all_starts = windows.starts().to(frames.device)
    gen = torch.Generator(device="cpu").manual_seed(seed)
    settled: int | None = None
    bar = _bar(config.max_steps, f"run {index + 1}", progress)
    step = 0
    try:
        for step in range(1, config.max_steps + 1):
            starts = all_starts
            if config.batch_windows and config.batch_windows < windows.count:
                pick = torch.randperm(windows.count, generator=gen)[: config.batch_windows]
                starts = all_starts[pick.to(frames.device)]
            length = _horizon(step, config, nc, first)
            frame_ids, inverse = distinct_frames(windows.index(starts)[:, :length])
            z_win = encoder(frames[frame_ids])[inverse]
            pred = block(z_win[:, :nc], length, dt, window_index=starts)
            loss, parts = latent_loss(z_win, pred, first, prior=config.prior, use_kl=config.use_kl)
            if not torch.isfinite(loss):
                raise FloatingPointError(f"loss became non-finite at step {step}")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            consts = {k: float(v.detach()) for k, v in block.constants().items()}
            if not all(math.isfinite(v) for v in consts.values()):
                raise FloatingPointError(f"a constant became non-finite at step {step}")
            lv = float(loss.detach())
            hist["step"].append(step)
            hist["loss"].append(lv)
            hist["mse"].append(parts["mse"])
            hist["kl"].append(parts["kl"])
            for n in names:
                hist["constants"][n].append(consts[n])
            record.final, record.loss, record.steps = consts, lv, step
            if callback is not None:
                callback(StepInfo(index, step, lv, parts["mse"], parts["kl"], consts))
            if bar is not None:
                bar.update(1)
                if step % 10 == 0:
                    bar.set_postfix_str(_postfix(lv, consts))
            if step >= max(config.min_steps, config.horizon_warmup) and step % 10 == 0:
                moving = _relative_motion(hist, config.patience)
                if settled is None and moving < config.tol * 10:
                    settled = step  # close: lower every learning rate so the constants settle precisely
                    for g, lr0 in zip(opt.param_groups, base_lrs):
                        g["lr"] = lr0 * config.settle_factor
                elif settled is not None and step - settled >= config.patience and moving < config.tol:
                    record.converged = True
                    break
    except (FloatingPointError, FitodeError) as exc:
        record.status, record.error, record.steps = "failed", str(exc), step
    except KeyboardInterrupt:
        # keep what the run had; fit_frames starts no further run and marks the result incomplete
        record.status, record.error = "interrupted", f"interrupted at step {step}"
    finally:
        if bar is not None:
            bar.close()
    record.wall_s = time.perf_counter() - t0
    record.history = hist
    return _Run(record, encoder, block)


def _horizon(step: int, config: TrainConfig, n_context: int, first: int) -> int:
    """Frames per window at this step: a few predicted frames at first, the whole window after warm-up.

    Far from the true constants a 20-frame rollout can grow by many orders of magnitude, and its
    error then drowns both the gradient of the constants and the KL term that keeps the encoder
    alive. Short rollouts first let the constants approach the data before the horizon grows.
    """
    shortest = max(n_context, first + 2)
    if config.horizon_warmup <= 0 or step >= config.horizon_warmup:
        return config.window
    frac = step / config.horizon_warmup
    return min(config.window, shortest + int(frac * (config.window - shortest + 1)))


def _relative_motion(hist: dict, patience: int) -> float:
    """Largest relative change, over the last `patience` steps, of any constant or of the mean loss."""
    if len(hist["step"]) <= 2 * patience:
        return math.inf
    worst = 0.0
    for series in hist["constants"].values():
        now, then = series[-1], series[-1 - patience]
        worst = max(worst, abs(now - then) / max(abs(now), 1e-3))
    recent = float(np.mean(hist["loss"][-patience:]))
    before = float(np.mean(hist["loss"][-2 * patience: -patience]))
    worst = max(worst, 0.1 * abs(recent - before) / max(abs(before), 1e-12))
    return worst


def _bar(total: int, desc: str, enabled: bool):
    if not enabled:
        return None
    from tqdm.auto import tqdm
    return tqdm(total=total, desc=desc, leave=False, dynamic_ncols=True)


def _postfix(loss: float, consts: Mapping[str, float]) -> str:
    return f"loss={loss:.3g} " + " ".join(f"{k}={v:.4g}" for k, v in consts.items())


def select_runs(runs: list[RunRecord], factor: float, statuses: tuple[str, ...] = ("ok",)) -> list[int]:
    """Runs the estimate is taken from: finite, and final loss within `factor` of the lowest."""
    ok = [r for r in runs if r.status in statuses and math.isfinite(r.loss)]
    if not ok:
        return []
    best = min(r.loss for r in ok)  # MSE and KL are both >= 0
    return [r.index for r in ok if r.loss <= best * factor + 1e-12]


def fit_frames(frames: torch.Tensor, dt: float, system: OdeSystem, params: Mapping[str, ParamSpec],
               config: TrainConfig, *, train_frames: int | None = None, init: Mapping[str, float] | None = None,
               callback: Callback | None = None, progress: bool = False, meta: dict | None = None) -> FitResult:
    """All restarts on normalised frames (T, C, H, W); training uses the first train_frames."""
    device = torch.device(config.device)
    frames = frames.to(device)
    n_total = frames.shape[0]
    n_train = n_total if train_frames is None else int(train_frames)
    if n_train < config.window + 1:
        raise TrainingError(f"{n_train} training frames are fewer than one window of {config.window} plus one; "
                            "use a longer clip, a smaller --stride or a shorter window")
    inits = restart_inits(system, params, config.restarts, config.seed, init)
    if config.workers > 1 and len(inits) > 1:
        runs = _parallel_runs(frames[:n_train], dt, system, params, config, inits, callback, progress)
    else:
        runs = []
        for i, row in enumerate(inits):
            runs.append(train_run(frames[:n_train], dt, system, params, config, row, index=i,
                                  seed=config.seed * 1000 + i, callback=callback, progress=progress))
            if runs[-1].record.status == "interrupted":
                break
    records = [r.record for r in runs]
    interrupted = any(r.status == "interrupted" for r in records)
    selected = select_runs(records, config.selection_factor)
    if not selected and interrupted:
        selected = select_runs(records, config.selection_factor, statuses=("ok", "interrupted"))
        if not selected:
            raise KeyboardInterrupt
    if not selected:
        errors = "; ".join(f"run {r.index + 1}: {r.error}" for r in records)
        raise TrainingError(f"every run failed ({errors})")
    by_index = {r.index: r for r in records}  # an interrupted parallel fit may lack some runs
    best = min(selected, key=lambda i: by_index[i].loss)
    estimates = {}
    for name in system.learnable:
        vals = np.array([by_index[i].final[name] for i in selected])
        unit = params.get(name, ParamSpec()).unit
        estimates[name] = Estimate(float(vals.mean()), float(vals.std()) if len(vals) > 1 else 0.0, len(vals), unit)
    latent, rollout = _trajectories(next(r for r in runs if r.record.index == best), frames, dt)
    return FitResult(
        parameters=estimates, runs=records, selected=selected, best=best,
        latent=latent, rollout=rollout, time=np.arange(n_total) * dt, train_frames=n_train, dt=dt,
        states=list(system.states), equation=system.text, fixed=dict(system.fixed),
        settings={**asdict(config), "prior": list(config.prior)}, selection_factor=config.selection_factor,
        meta={**(meta or {}), "interrupted": interrupted},
    )


def _worker_init() -> None:
    # one thread per worker: on small tensors, processes scale where intra-op threads do not
    torch.set_num_threads(1)


def _worker_run(args) -> _Run:
    return train_run(*args[:6], index=args[6], seed=args[7])


def _parallel_runs(frames, dt, system, params, config, inits, callback, progress) -> list[_Run]:
    """Restarts in a pool of spawned processes; the callback sees each run's steps when it ends."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    jobs = [(frames.cpu(), dt, system, params, config, row, i, config.seed * 1000 + i) for i, row in enumerate(inits)]
    bar = _bar(len(jobs), f"{len(jobs)} runs on {config.workers} workers", progress)
    runs: list[_Run] = [None] * len(jobs)  # type: ignore[list-item]
    def collect(fut, timeout=None) -> None:
        run = fut.result(timeout=timeout)
        runs[futures[fut]] = run
        if callback is not None:
            h = run.record.history
            for k, step in enumerate(h["step"]):
                callback(StepInfo(run.record.index, step, h["loss"][k], h["mse"][k], h["kl"][k],
                                  {n: v[k] for n, v in h["constants"].items()}))
        if bar is not None:
            bar.update(1)

    with ProcessPoolExecutor(config.workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_worker_init) as pool:
        futures = {pool.submit(_worker_run, job): job[6] for job in jobs}
        try:
            for fut in as_completed(futures):
                collect(fut)
        except KeyboardInterrupt:
            # a SIGINT sent to this process alone (a terminal's Ctrl-C reaches the workers too):
            # pass it on, so each run stops where it is and hands back what it had
            for fut in futures:
                fut.cancel()  # restarts still queued never start
            for proc in list(getattr(pool, "_processes", {}).values()):
                try:
                    os.kill(proc.pid, signal.SIGINT)
                except (ProcessLookupError, OSError):
                    pass
            for fut in futures:
                if runs[futures[fut]] is None and not fut.cancelled():
                    try:
                        collect(fut, timeout=60)
                    except Exception:  # a worker that died on the signal has nothing to give
                        fut.cancel()
            if not any(r is not None and r.record.status == "interrupted" for r in runs):
                raise
    if bar is not None:
        bar.close()
    runs = [r for r in runs if r is not None]
    device = frames.device
    for run in runs:
        run.encoder.to(device)
        run.block.to(device)
    return runs


@torch.no_grad()
def _trajectories(run: _Run, frames: torch.Tensor, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The best run's latent for every frame, and its physics rollout from the first frames."""
    encoder, block = run.encoder, run.block
    encoder.eval()
    latent = torch.cat([encoder(chunk) for chunk in frames.split(512)])
    try:
        rollout = block(latent[None, : block.n_context], frames.shape[0], dt)[0]
    except FitodeError:  # a long extrapolation may leave the equation's domain; show what is finite
        rollout = torch.full_like(latent, float("nan"))
    return latent.cpu().double().numpy(), rollout.cpu().double().numpy()
