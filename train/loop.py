"""The training loop: R restarts trained together as one batched model.

Every restart has its own encoder weights, constants and gauge, stacked along a leading axis;
one step encodes each distinct frame of the batch once per restart, rolls the physics out from
each window's first frames and sums the restarts' losses, so each restart's gradients stay its
own. A restart that converges or fails is frozen (BatchedAdam leaves it exactly where it is)
while the others go on. Nothing in the step waits for the host: non-finite losses and gradients
freeze their restart through a device-side mask, and the host looks (history, stopping rule,
the failed term's name) only every `check_every` steps.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
import torch

from fitode.codegen import PhysicsBlock
from fitode.eqparse import OdeSystem, ParamSpec
from fitode.eqparse.gauge import StateGauge
from fitode.errors import FitodeError, TrainingError

from . import interrupts
from .config import ENCODER_NAMES, TrainConfig
from .encoders import BatchedEncoder
from .latent_map import LR_FACTOR, Gauge
from .history import History
from .loss import restart_losses
from .observe import ObservationModel
from .optim import BatchedAdam
from .result import RunRecord
from .stopping import StopRule, horizon
from .windows import Windows, distinct_frames


@dataclass
class StepInfo:
    """What a callback sees after every optimisation step of every restart."""

    run: int
    step: int
    loss: float
    mse: float
    kl: float
    constants: dict[str, float]


Callback = Callable[[StepInfo], object]


@dataclass
class Trained:
    """The loop's outcome: one record per restart and the batched model that produced them."""

    records: list[RunRecord]
    encoder: torch.nn.Module
    block: PhysicsBlock
    gauge: Gauge


def train_restarts(frames: torch.Tensor, dt: float, system: OdeSystem, params: Mapping[str, ParamSpec],
                   config: TrainConfig, inits: Sequence[Mapping[str, float]], *, seeds: Sequence[int],
                   observation: ObservationModel, plan: Mapping[str, StateGauge],
                   callback: Callback | None = None, progress: bool = False,
                   targets: Mapping[int, np.ndarray] | None = None) -> Trained:
    """Train len(inits) restarts on prepared frames (T, C, H, W) already on the target device.
    targets: {restart: (T,) latent} whose encoder first learns that latent (see distill)."""
    t0 = time.perf_counter()
    if config.window is None or config.encoder not in ENCODER_NAMES:
        raise ValueError("train_restarts takes a resolved config (fitode.train.plan.make_plan): a window and an encoder")
    n_runs = len(inits)
    device = frames.device
    windows = Windows(frames.shape[0], config.window)
    block = PhysicsBlock(system, params, integrator=config.integrator, substeps=config.substeps,
                         initial_state=config.initial_state, n_windows=windows.count, restarts=n_runs,
                         check_finite=False)
    nc, first = block.n_context, block.anchor + 1  # first: the first frame that is a prediction
    if config.window <= nc:
        raise TrainingError(f"window of {config.window} frames is too short for an equation that needs {nc} to start")
    block.set_constants({n: [row[n] for row in inits] for n in system.learnable}, clip=True)
    block = block.to(device)
    encoder = observation.encoder(config.encoder, tuple(frames.shape[1:]), system.dim, seeds,
                                  output_mean=config.prior[0], output_std=config.prior[1]).to(device)
    gauge = Gauge(plan, system.states, n_runs, config.prior, enabled=config.gauge).to(device)
    # a latent in the state's own units is not standardised to the prior: the KL term would only
    # add a constant (nothing in the readout moves) that hides the fit's progress from the stopping rule
    use_kl = config.use_kl and not observation.physical_units
    if targets and any(p.requires_grad for p in encoder.parameters()):  # a fixed readout has nothing to learn
        distill(encoder, frames, targets, config)
    gauge.enter_domain(encode_all(encoder, frames))

    groups = [{"params": list(encoder.parameters()), "lr": config.lr, "name": "encoder"}]
    const_params = {}
    for g in block.param_groups(lr=config.const_lr):
        if g["kind"] == "constant":
            const_params[g["name"]] = g["params"][0]
        # per-window initial derivatives move with the encoder's latents, not at a constant's pace
        lr = config.lr * 10 if g["kind"] == "initial_state" else g["lr"]
        groups.append({"params": g["params"], "lr": lr, "name": g["name"]})
    groups.append({"params": [gauge.log_scale], "lr": config.const_lr, "name": "gauge scale"})
    groups.append({"params": [gauge.offset], "lr": config.const_lr * LR_FACTOR, "name": "gauge offset"})
    opt = BatchedAdam(groups, n_runs)

    names = list(system.learnable)
    records = [RunRecord(index=r, seed=int(seeds[r]), init=dict(inits[r]), final={}, loss=math.inf, steps=0,
                         status="ok", history=History.for_constants(names)) for r in range(n_runs)]
    rules = [StopRule(config) for _ in range(n_runs)]
    active = torch.ones(n_runs, dtype=torch.bool, device=device)
    all_starts = windows.starts().to(device)
    gen = torch.Generator(device="cpu").manual_seed(int(config.seed))
    buffer: list[tuple] = []
    bar = _bar(config.max_steps, f"{n_runs} restart{'s' if n_runs != 1 else ''}", progress)
    step, length = 0, config.window
    # the restarts still training (None: all): a stopped one is left out of the step's work, not
    # only frozen, so R restarts cost what their steps cost rather than R times the longest's
    can_leave_out = _runs_some(encoder) and config.initial_state != "learnable"
    running: torch.Tensor | None = None

    def look(step: int) -> None:
        """The host's look every check_every steps: history, failures, the stopping rule."""
        nonlocal running
        _flush(buffer, records, names, callback)
        for r, rec in enumerate(records):
            if rec.status == "failing":
                rec.status, rec.stop_reason = "failed", "non-finite"
                rec.error = _explain(encoder, block, gauge, frames, windows, length, dt, r, rec.steps + 1)
        on = active.tolist()
        for r, rec in enumerate(records):
            if not on[r]:
                continue
            verdict = rules[r].update(step, rec.history)
            if verdict == "settle":
                opt.lr_mult[r] *= config.settle_factor
            elif verdict == "converged":
                active[r] = False
                rec.converged, rec.stop_reason = True, "converged"
        for name, factor in block.follow_scales().items():
            opt.rescaled(const_params[name], factor)
        now = active.tolist()
        if can_leave_out and 0 < sum(now) < n_runs:
            running = torch.tensor([r for r, a in enumerate(now) if a], device=device)
        if bar is not None:
            bar.update(step - bar.n)
            bar.set_postfix_str(_postfix(records, on))

    try:
        for step in range(1, config.max_steps + 1):
            interrupts.check()  # a signal stops the fit here, never inside a step (see interrupts.py)
            starts = all_starts
            if config.batch_windows and config.batch_windows < windows.count:
                pick = torch.randperm(windows.count, generator=gen)[: config.batch_windows]
                starts = all_starts[pick.to(device)]
            length = horizon(step, config, nc, first)
            frame_ids, inverse = distinct_frames(windows.index(starts)[:, :length])
            if running is None:
                z = encoder(frames[frame_ids])  # (R, F, d)
            else:
                z = encoder(frames[frame_ids], restarts=running)  # (R running, F, d)
            z_win = z[:, inverse]  # (R, B, L, d)
            x_pred = block(gauge.to_state(z_win[:, :, :nc], running), length, dt, window_index=starts,
                           restarts=running)
            total, mse, kl = restart_losses(z_win, gauge.to_latent(x_pred, running), first, prior=config.prior,
                                            use_kl=use_kl)
            extra = observation.regulariser(z)
            if extra is not None:
                total = total + extra
            if running is not None:  # back to one entry per restart: NaN for those left out (inactive)
                total, mse, kl = (v.new_full((n_runs,), math.nan).index_copy(0, running, v)
                                  for v in (total, mse, kl))
            ok = active & torch.isfinite(total)
            opt.zero_grad()
            torch.where(ok, total, torch.zeros_like(total)).sum().backward()
            ok = ok & opt.finite_grads()
            opt.step(ok)
            with torch.no_grad():
                consts = torch.stack([v.detach() for v in block.constants().values()], dim=1) if names else \
                    torch.zeros(n_runs, 0, device=device)
            buffer.append((step, active.clone(), ok, total.detach(), mse.detach(), kl.detach(), consts))
            active = ok
            if step % config.check_every == 0 or step == config.max_steps:
                look(step)
                if not bool(active.any()):
                    break
    except KeyboardInterrupt:
        _flush(buffer, records, names, None)
        for r, on in enumerate(active.tolist()):
            if on and records[r].status == "ok":
                records[r].status, records[r].stop_reason = "interrupted", "interrupted"
                records[r].error = f"interrupted at step {records[r].steps}"
    finally:
        if bar is not None:
            bar.close()
    for r, rec in enumerate(records):
        if rec.status == "failing":  # failed in the steps after the last look
            rec.status, rec.stop_reason = "failed", "non-finite"
            rec.error = _explain(encoder, block, gauge, frames, windows, length, dt, r, rec.steps + 1)
        if rec.status == "ok" and not rec.stop_reason:
            rec.stop_reason = "max_steps"
        rec.wall_s = time.perf_counter() - t0
        rec.gauge = gauge.values(r)
    return Trained(records, encoder, block, gauge)


DISTILL_STEPS = 300


@torch.no_grad()
def encode_all(encoder, frames: torch.Tensor) -> torch.Tensor:
    """Every restart's latent of every frame, (R, T, d), encoded in chunks to bound the memory."""
    return torch.cat([encoder(chunk) for chunk in frames.split(512)], dim=1)


def distill(encoder, frames: torch.Tensor, targets: Mapping[int, np.ndarray], config: TrainConfig) -> None:
    """Teach the encoders of some restarts a given latent, (T,) or (T, k) for the first k latent
    dimensions, each column standardised to the prior, before the joint training: a start from
    the data carries the readout of the frames it was fitted to."""
    n_runs = encoder.restarts
    mean, std = config.prior
    columns = {r: np.asarray(z, dtype=float).reshape(len(z), -1) for r, z in targets.items()}
    k = max(z.shape[1] for z in columns.values())
    target = torch.zeros(n_runs, frames.shape[0], k, device=frames.device)
    weight = torch.zeros(n_runs, 1, k, device=frames.device)  # which latent dimensions each restart is taught
    active = torch.zeros(n_runs, dtype=torch.bool, device=frames.device)
    for r, z in columns.items():
        z = mean + std * (z - z.mean(axis=0)) / np.where(z.std(axis=0) > 0, z.std(axis=0), 1.0)
        target[r, : len(z), : z.shape[1]] = torch.as_tensor(z[: frames.shape[0]], dtype=target.dtype)
        weight[r, 0, : z.shape[1]] = 1.0
        active[r] = True
    n = min(frames.shape[0], min(len(z) for z in columns.values()))
    opt = BatchedAdam([{"params": list(encoder.parameters()), "lr": config.lr * 10, "name": "encoder"}], n_runs)
    # only the taught restarts' encoders run: the others' would be computed and thrown away
    taught = torch.tensor(sorted(targets), device=frames.device) if _runs_some(encoder) else None
    # as the search that found the latent: no more steps than the fit itself may take
    for _ in range(min(DISTILL_STEPS, config.max_steps)):
        interrupts.check()
        if taught is None:
            loss = _distill_loss(encoder(frames[:n])[..., :k], target[:, :n], weight)
        else:
            part = _distill_loss(encoder(frames[:n], restarts=taught)[..., :k], target[taught, :n], weight[taught])
            loss = target.new_zeros(n_runs).index_copy(0, taught, part)
        opt.zero_grad()
        torch.where(active, loss, torch.zeros_like(loss)).sum().backward()
        opt.step(active)


def _distill_loss(z: torch.Tensor, target: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """(R,) mean squared miss of the taught latent dimensions, per restart."""
    return ((z - target).pow(2) * weight).sum(dim=2).mean(dim=1) / weight.sum(dim=(1, 2)).clamp_min(1)


def _runs_some(encoder) -> bool:
    """Whether the encoder can run some restarts only (BatchedEncoder's `restarts`, or an encoder
    that says it can); an observation model's own encoder may not, and then runs them all."""
    if isinstance(encoder, BatchedEncoder):
        return type(encoder).forward is BatchedEncoder.forward
    return bool(getattr(encoder, "runs_some", False))


def _flush(buffer: list[tuple], records: list[RunRecord], names: list[str], callback: Callback | None) -> None:
    """Move the buffered steps to the host in one transfer, append them to each run's history,
    empty the buffer, and only then call the callback (which may raise KeyboardInterrupt)."""
    if not buffer:
        return
    steps = [b[0] for b in buffer]
    # Python lists in one conversion each: indexing a tensor element by element cost most of the
    # loop's bookkeeping (a tensor made per number); the floats are the same
    was, ok, loss, mse, kl = (torch.stack([b[i] for b in buffer]).cpu().tolist() for i in range(1, 6))
    consts = torch.stack([b[6] for b in buffer]).cpu().double().tolist()
    buffer.clear()
    seen: list[StepInfo] = []
    for r, rec in enumerate(records):
        for k, step in enumerate(steps):
            if not was[k][r]:
                continue
            if not ok[k][r]:
                rec.status, rec.steps = "failing", step - 1  # frozen at the values that failed at this step
                break
            values = dict(zip(names, consts[k][r]))
            rec.history.append(step, loss[k][r], mse[k][r], kl[k][r], values)
            rec.final, rec.loss, rec.steps = values, loss[k][r], step
            if callback is not None:
                seen.append(StepInfo(r, step, loss[k][r], mse[k][r], kl[k][r], values))
    if callback is not None:
        for info in seen:
            callback(info)


@torch.no_grad()
def _explain(encoder, block: PhysicsBlock, gauge: Gauge, frames, windows: Windows, length: int, dt: float,
             r: int, step: int) -> str:
    """Name the term that went non-finite: replay restart r (frozen where it failed) on every window."""
    try:
        idx = windows.index(windows.starts().to(frames.device))[:, :length]
        z = encode_all(encoder, frames)[:, idx]  # (R, W, L, d)
        head = gauge.to_state(z[:, :, :block.n_context])
        err = block.explain(head, length, dt, restart=r)
        return f"{err} (step {step})"
    except FitodeError as exc:  # the replay itself could not run: still say when
        return f"{exc} (step {step})"


def _bar(total: int, desc: str, enabled: bool):
    if not enabled:
        return None
    from tqdm.auto import tqdm
    return tqdm(total=total, desc=desc, leave=False, dynamic_ncols=True)


def _postfix(records: list[RunRecord], on: list[bool]) -> str:
    live = [r for r, a in zip(records, on) if a and r.history.loss]
    if not live:
        return "all stopped"
    best = min(live, key=lambda r: r.loss)
    consts = " ".join(f"{k}={v:.4g}" for k, v in best.final.items())
    return f"{len(live)} running, best loss={best.loss:.3g} {consts}"
