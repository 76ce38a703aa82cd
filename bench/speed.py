"""speed: per-frame against per-window encoding, time per step, per epoch and to a converged estimate.

fitode's trainer encodes every distinct frame of a batch once per step and gathers the windows
from that encoded sequence by index (per-frame). The official code of the paper encodes each
window's frames separately, so a frame is encoded once for every window that contains it
(per-window, frames[window_index]: about window-length times the encoder work). Both compute
the same loss (the table's last column checks it at the same weights).

Video: the paper's intensity dataset (fitode.synth.paper_video, damped oscillator, 270 frames
at dt 0.2 s) at 50x50, and the same frames resized to 64x114 (what `fitode VIDEO` makes of a
480x270 video: short side 64). Equation given as text, every TrainConfig default: the MLP
encoder, RK4, 20-frame windows, all windows in every step (so one step is one epoch, one pass
over all windows, unless --batch-windows is given).

Measured with --threads torch threads (default 2), each part in a fresh process:
- time per step: one optimisation step (encode, roll out, loss, backward, Adam) at the full
  window length, built here from the trainer's parts (encoder, PhysicsBlock, latent_loss, the
  trainer's optimiser groups) so that only the encoding differs; the two modes alternate, step
  by step, --reps times, so a busy machine slows both alike; the table gives the minimum (the
  machine's cost when nothing else runs) and the median. Per epoch: steps per pass over all
  windows x the minimum.
- time to a converged estimate: per-frame, `fitode.fit` to the trainer's stopping rule,
  measured (wall and CPU time); per-window, estimated as that time x the ratio of the two
  modes' minimum step times (the same loss gives the same steps, each dearer by that ratio; a
  per-window fit to convergence would take many minutes).
- peak memory: the peak RSS of a process that loads the frames and takes 5 steps, and its rise
  over the RSS before the first step.

- restarts: ms per step of the real batched loop (fitode.train.loop, subspace and all) with 1, 4,
  8 and 16 restarts trained as one model, on cpu and, where torch sees one, cuda; the sizes
  alternate, repetition by repetition, and the table gives the minimum over hand-overs of 5
  steps; restart-steps per second = restarts / (s per step).

Shared machines: other processes slow a 2-thread step far more than their share (the threads
wait for each other), so the load average is printed beside the numbers; trust the minimum
and the ratios more than the medians.

    python bench/speed.py              # or: fitode bench speed (58 s on 2 idle cores, 4-8 min busy)
    python bench/speed.py --quick      # smoke test

Prints the table and the per-window / per-frame ratios; writes <out>/speed.json.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402

EQUATION = "z'' + g1*z' + g0*z = 0"
SIZES = {"50x50": (50, 50), "64x114": (64, 114)}
MODES = ("per-frame", "per-window")
FULL = {"n_frames": 270, "sizes": SIZES, "reps": 40, "max_steps": None, "restarts": (1, 4, 8, 16),
        "restart_steps": 60, "rounds": 3}
QUICK = {"n_frames": 40, "sizes": {"16x28": (16, 28)}, "reps": 3, "max_steps": 8, "restarts": (1, 2),
         "restart_steps": 15, "rounds": 1}
MEMORY_STEPS = 5
PARTS = ("all", "encodings", "restarts", "answer", "compile")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=None)
    parser.add_argument("--threads", type=int, default=None, help="torch threads (default 2; --quick: 1)")
    parser.add_argument("--sizes", default=None, help="comma-separated HxW sizes (default 50x50,64x114)")
    parser.add_argument("--reps", type=int, default=None, help="timed steps per mode (default 40)")
    parser.add_argument("--batch-windows", type=int, default=None,
                        help="windows per step (default: TrainConfig's, all of them)")
    parser.add_argument("--part", choices=PARTS, default="all",
                        help="measure one part only: encodings (per-frame vs per-window), restarts (batched "
                             "restarts), answer (one restart to a converged answer), compile (torch.compile of the "
                             "rollout against eager; not in all: its compilation alone takes about a minute); "
                             "default all")


def frames_for(size: tuple[int, int], n_frames: int) -> tuple[np.ndarray, float]:
    from fitode.synth import paper_video

    h, w = size
    if h == w:
        v = paper_video("intensity", n_frames=n_frames, size=h)
        return v.frames, v.dt
    import cv2

    v = paper_video("intensity", n_frames=n_frames, size=min(h, w))
    frames = np.stack([cv2.resize(f, (w, h), interpolation=cv2.INTER_LINEAR) for f in v.frames])
    return frames, v.dt


class Stepper:
    """One optimisation step of the trainer, per-frame or per-window, at the full window length."""

    def __init__(self, frames: np.ndarray, dt: float, mode: str, batch_windows: int | None, seed: int = 0):
        import torch

        from fitode.api import as_frames
        from fitode.codegen import PhysicsBlock
        from fitode.eqparse import parse
        from fitode.train.encoders import make_encoder, normalise_frames
        from fitode.train.trainer import TrainConfig
        from fitode.train.windows import Windows

        self.cfg = cfg = TrainConfig(window=20)
        torch.manual_seed(seed)
        self.mode, self.dt = mode, float(dt)
        self.x = normalise_frames(as_frames(frames))
        system = parse(EQUATION)
        self.windows = Windows(self.x.shape[0], cfg.window)
        self.encoder = make_encoder("mlp", tuple(self.x.shape[1:]), system.dim)  # the paper's, as the official code
        self.block = PhysicsBlock(system, {}, integrator=cfg.integrator, substeps=cfg.substeps, initial_state=cfg.initial_state,
                                  n_windows=self.windows.count)
        self.first = getattr(self.block, "anchor", self.block.n_context - 1) + 1
        groups = [{"params": list(self.encoder.parameters()), "lr": cfg.lr}] + self.block.param_groups(lr=cfg.const_lr)
        self.opt = torch.optim.Adam(groups)
        self.batch = min(batch_windows or self.windows.count, self.windows.count)
        self.gen = torch.Generator().manual_seed(seed)

    def loss(self):
        import torch

        from fitode.train.loss import latent_loss
        from fitode.train.windows import distinct_frames

        starts = self.windows.starts()
        if self.batch < self.windows.count:
            starts = starts[torch.randperm(self.windows.count, generator=self.gen)[: self.batch]]
        index = self.windows.index(starts)
        if self.mode == "per-frame":
            ids, inverse = distinct_frames(index)
            z = self.encoder(self.x[ids])[inverse]
        else:  # the official code's way: every window's frames through the encoder
            z = self.encoder(self.x[index.reshape(-1)]).reshape(*index.shape, -1)
        pred = self.block(z[:, : self.block.n_context], self.cfg.window, self.dt, window_index=starts)
        loss, _ = latent_loss(z, pred, self.first, prior=self.cfg.prior, use_kl=self.cfg.use_kl)
        return loss

    def step(self) -> float:
        loss = self.loss()
        self.opt.zero_grad(set_to_none=True)
        loss.backward()
        self.opt.step()
        return float(loss.detach())

    @property
    def frames_per_step(self) -> int:
        if self.mode == "per-window":
            return self.batch * self.cfg.window
        from fitode.train.windows import distinct_frames

        return int(distinct_frames(self.windows.index(self.windows.starts()[: self.batch]))[0].numel())


def time_steps(task: dict[str, Any]) -> dict[str, Any]:
    """Both modes in one process, steps alternating, so a busy machine slows both alike."""
    import torch

    frames, dt = frames_for(tuple(task["size"]), task["n_frames"])
    steppers = {m: Stepper(frames, dt, m, task["batch_windows"]) for m in MODES}
    with torch.no_grad():  # same initial weights (same seed): the same loss, whichever encoding
        first = {m: float(s.loss()) for m, s in steppers.items()}
    for s in steppers.values():
        for _ in range(2):  # allocator and first-use costs
            s.step()
    wall = {m: [] for m in MODES}
    cpu = {m: [] for m in MODES}
    for _ in range(task["reps"]):
        for m, s in steppers.items():
            t0, c0 = time.perf_counter(), time.process_time()
            s.step()
            wall[m].append(time.perf_counter() - t0)
            cpu[m].append(time.process_time() - c0)
    out = {}
    for m, s in steppers.items():
        out[m] = {"frames_encoded_per_step": s.frames_per_step, "windows": s.windows.count,
                  "windows_per_step": s.batch, "step_min_s": min(wall[m]), "step_median_s": float(np.median(wall[m])),
                  "step_cpu_min_s": min(cpu[m]), "step_times": wall[m], "first_loss": first[m]}
    out["loss_diff"] = abs(first["per-window"] - first["per-frame"]) / max(abs(first["per-frame"]), 1e-12)
    return out


def peak_memory(task: dict[str, Any]) -> dict[str, Any]:
    """Peak RSS of a fresh process that loads the frames and takes a few steps in one mode."""
    frames, dt = frames_for(tuple(task["size"]), task["n_frames"])
    s = Stepper(frames, dt, task["mode"], task["batch_windows"])
    before = bc.current_rss_mb()
    for _ in range(MEMORY_STEPS):
        s.step()
    peak = bc.peak_rss_mb()
    return {"rss_before_mb": before, "peak_rss_mb": peak, "rss_rise_mb": peak - before}


def converge(task: dict[str, Any]) -> dict[str, Any]:
    """A real per-frame fit (fitode.fit, one restart, defaults) to the trainer's stopping rule."""
    import fitode
    from fitode.errors import FitodeError

    frames, dt = frames_for(tuple(task["size"]), task["n_frames"])
    opts = {} if task["batch_windows"] is None else {"batch_windows": task["batch_windows"]}
    if task["max_steps"]:
        opts["max_steps"] = task["max_steps"]
    rec = bc.StepRecorder(names=("g0", "g1"))
    t0, c0 = time.perf_counter(), time.process_time()
    out: dict[str, Any] = {}
    try:
        run = fitode.fit(frames, dt, eq=EQUATION, restarts=1, progress=False, callback=rec, **opts).runs[0]
        out.update(steps=run.steps, converged=bool(run.converged), estimate=dict(run.final))
    except FitodeError as exc:
        out.update(steps=len(rec.runs.get(0, [])), converged=False, error=str(exc))
    out.update(wall_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0)
    return out


ANSWER = {"n_frames": 519, "size": 50, "init": {"g0": 0.5, "g1": 0.5}, "truth": {"g0": 4.0016, "g1": 0.08},
          "bounds": {"g0": 0.005, "g1": 0.10}, "target_s": 5.0, "repeats": 3}
ANSWER_QUICK = {**ANSWER, "n_frames": 60, "size": 16, "repeats": 1, "max_steps": 30}


def one_answer(task: dict[str, Any]) -> dict[str, Any]:
    """One restart of fitode.fit on the paper's intensity video from the paper's default start, to
    its own stopping rule: wall time of the call (imports done before), steps, and from which step
    the constants stayed inside the bounds for good."""
    import fitode
    import fitode.api  # noqa: F401  (imports are not the fit's time)
    import fitode.train.trainer  # noqa: F401
    from fitode.synth import paper_video

    v = paper_video("intensity", n_frames=task["n_frames"], dt=0.2, size=task["size"])
    opts = {"max_steps": task["max_steps"]} if task.get("max_steps") else {}
    t0 = time.perf_counter()
    res = fitode.fit(v.frames, v.dt, eq=EQUATION, restarts=1, init=task["init"], progress=False, **opts)
    wall = time.perf_counter() - t0
    run = res.runs[0]
    inside = np.ones(len(run.history.step), dtype=bool)
    for name, bound in task["bounds"].items():
        series = np.asarray(run.history.constants[name])
        inside &= np.abs(series / task["truth"][name] - 1) < bound
    outside = np.flatnonzero(~inside)
    good_from = None
    if len(inside) and inside[-1]:
        good_from = int(run.history.step[outside[-1] + 1 if len(outside) else 0])
    return {"wall_s": wall, "steps": run.steps, "stop_reason": run.stop_reason, "good_from": good_from,
            "estimate": {k: e.value for k, e in res.parameters.items()}, "verdict": res.verdicts["g0"]["verdict"],
            "loop_s": run.wall_s, "load_after": round(os.getloadavg()[0], 2)}


def answer_table(rows: list[dict[str, Any]], task: dict[str, Any]) -> str:
    truth = task["truth"]
    out = [f"one restart to the answer: {task['n_frames']} frames at {task['size']}x{task['size']}, from "
           f"g0 = g1 = {task['init']['g0']}, fitode.fit(restarts=1), each in a fresh process",
           "repeat  wall s  steps  stop       inside from  g0 error  g1 error  verdict   load (1 min)"]
    for i, r in enumerate(rows):
        e = r["estimate"]
        out.append(f"{i + 1:>6}  {r['wall_s']:>6.2f}  {r['steps']:>5}  {r['stop_reason']:<9}  "
                   f"{'never' if r['good_from'] is None else r['good_from']:>11}  "
                   f"{100 * (e['g0'] / truth['g0'] - 1):>+7.2f}%  {100 * (e['g1'] / truth['g1'] - 1):>+7.1f}%  "
                   f"{r['verdict']:<8}  {r['load_after']}")
    best = min(rows, key=lambda r: r["wall_s"])
    e = best["estimate"]
    met = (best["stop_reason"] == "converged" and best["wall_s"] <= task["target_s"]
           and all(abs(e[k] / truth[k] - 1) < b for k, b in task["bounds"].items()))
    out.append(f"target (stopped by its own rule, g0 within {100 * task['bounds']['g0']:g}% and g1 within "
               f"{100 * task['bounds']['g1']:g}%, at most {task['target_s']:g} s): {'MET' if met else 'NOT MET'} "
               f"(fastest {best['wall_s']:.2f} s)")
    return "\n".join(out)


def time_compile(task: dict[str, Any]) -> dict[str, Any]:
    """The physics rollout (fwd + bwd, the part of a step that is thousands of tiny ops) eager and
    under torch.compile: ms per call after warm-up, and the first compiled call's wall time."""
    import torch

    from fitode.codegen import PhysicsBlock
    from fitode.eqparse import parse

    block = PhysicsBlock(parse(EQUATION), {}, integrator="rk4", restarts=task["restarts"],
                         n_windows=task["windows"], check_finite=False)
    head = torch.randn(task["restarts"], task["windows"], block.n_context, 1, requires_grad=True)

    def call(fn):
        fn(head, task["window"], 0.2).sum().backward()

    def per_call(fn, n=task["reps"]):
        call(fn)
        t0 = time.perf_counter()
        for _ in range(n):
            call(fn)
        return (time.perf_counter() - t0) / n

    out = {"eager_s": per_call(block)}
    t0 = time.perf_counter()
    try:
        compiled = torch.compile(block)
        call(compiled)
        out["compile_s"] = time.perf_counter() - t0
        out["compiled_s"] = per_call(compiled)
    except Exception as exc:  # noqa: BLE001 - no compiler, an unsupported op: report it, do not fail the bench
        out["error"] = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    return out


def compile_table(r: dict[str, Any], task: dict[str, Any]) -> str:
    head = (f"torch.compile of the rollout ({task['windows']} windows of {task['window']} frames, "
            f"{task['restarts']} restart(s), fwd + bwd)")
    if "error" in r:
        return f"{head}\neager {1e3 * r['eager_s']:.2f} ms; compile failed: {r['error']}"
    saved = r["eager_s"] - r["compiled_s"]
    pays = f"pays after {r['compile_s'] / saved:,.0f} calls" if saved > 0 else "never pays"
    return (f"{head}\neager {1e3 * r['eager_s']:.2f} ms, compiled {1e3 * r['compiled_s']:.2f} ms, first compiled "
            f"call {r['compile_s']:.1f} s: {pays} (one per step, one compile per window length)")


def time_restarts(task: dict[str, Any]) -> list[dict[str, Any]]:
    """ms per step of the batched loop for each restart count (and device), interleaved."""
    import torch

    from fitode.api import as_frames
    from fitode.eqparse import parse
    from fitode.eqparse.gauge import gauge_plan
    from fitode.train.config import TrainConfig
    from fitode.train.loop import train_restarts
    from fitode.train.observe import ObservationModel

    frames, dt = frames_for(tuple(task["size"]), task["n_frames"])
    system = parse(EQUATION)
    plan = gauge_plan(system)
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    best: dict[tuple[str, int], float] = {}
    for _ in range(task["rounds"]):
        for device in devices:
            prepared = ObservationModel().prepare(as_frames(frames).to(device))
            for n in task["restarts"]:
                stamps: list[float] = []
                cfg = TrainConfig(max_steps=task["steps"], min_steps=task["steps"], horizon_warmup=0, window=20,
                                  check_every=5, restarts=n, encoder="mlp", device=device)
                inits = [{"g0": 1.0 + 0.1 * i, "g1": 0.5} for i in range(n)]
                train_restarts(prepared.inputs, dt, system, {}, cfg, inits, seeds=list(range(n)),
                               observation=ObservationModel(), plan=plan,
                               callback=lambda info: info.run == 0 and stamps.append(time.perf_counter()))
                per_step = np.diff(np.asarray(stamps)[4::5]) / 5 if len(stamps) > 10 else [math.inf]
                key = (device, n)
                best[key] = min(best.get(key, math.inf), float(np.min(per_step)))
    return [{"device": d, "restarts": n, "step_s": v, "restart_steps_per_s": n / v} for (d, n), v in best.items()]


def restart_table(rows: list[dict[str, Any]]) -> str:
    out = ["size     device  restarts  ms/step (min)  restart-steps/s  cost vs 1 restart"]
    one = {(r["size"], r["device"]): r["step_s"] for r in rows if r["restarts"] == 1}
    for r in rows:
        base = one.get((r["size"], r["device"]))
        out.append(f"{r['size']:<8} {r['device']:<7} {r['restarts']:>8}  {1000 * r['step_s']:>13.1f}  "
                   f"{r['restart_steps_per_s']:>15.0f}  {r['step_s'] / base if base else math.nan:>16.2f}x")
    return "\n".join(out)


def table(rows: list[dict[str, Any]]) -> str:
    out = []
    for r in rows:
        est = r["mode"] == "per-window"
        out.append({"size": r["size"], "mode": r["mode"], "enc": bc.num(r["frames_encoded_per_step"]),
                    "min": bc.num(1e3 * r["step_min_s"], 1), "med": bc.num(1e3 * r["step_median_s"], 1),
                    "cpu": bc.num(1e3 * r["step_cpu_min_s"], 1), "epoch": bc.num(r["epoch_s"], 3),
                    "steps": bc.num(r["converge_steps"]),
                    "conv": bc.num(r["converge_s"], 1) + (" (est.)" if est else ""),
                    "cpu_conv": "" if est else bc.num(r["converge_cpu_s"], 1),
                    "peak": bc.num(r["peak_rss_mb"], 0), "rise": bc.num(r["rss_rise_mb"], 0),
                    "diff": f"{r['loss_diff']:.1e}" if est else ""})
    cols = [("size", "size"), ("encoding", "mode"), ("frames encoded/step", "enc"), ("ms/step min", "min"),
            ("ms/step median", "med"), ("CPU ms/step", "cpu"), ("s/epoch", "epoch"), ("steps to conv", "steps"),
            ("s to converge", "conv"), ("CPU s", "cpu_conv"), ("peak RSS MB", "peak"), ("RSS rise MB", "rise"),
            ("loss diff", "diff")]
    return bc.format_table(out, cols, title="ms/step: one optimisation step at the full window, modes alternating "
                                             "(min: least contended; CPU: process CPU time, all threads, min); "
                                             "s/epoch = steps per pass over all windows x min; per-window time to "
                                             "converge = the per-frame fit's time x the ratio of the min step times; loss diff: "
                                             "relative difference of the loss at the same weights")


def run(args: argparse.Namespace) -> int:
    from fitode.errors import FitodeError

    cfg = dict(QUICK if args.quick else FULL)
    if args.sizes:
        sizes = {}
        for item in args.sizes.split(","):
            try:
                h, w = (int(v) for v in item.lower().split("x"))
            except ValueError:
                raise FitodeError(f"--sizes: cannot read {item!r}; write HxW, e.g. 64x114") from None
            if not (8 <= h <= 1024 and 8 <= w <= 1024):
                raise FitodeError(f"--sizes: {item} is outside 8..1024 pixels a side")
            sizes[f"{h}x{w}"] = (h, w)
        cfg["sizes"] = sizes
    if args.reps is not None:
        cfg["reps"] = args.reps
    for value, flag in ((args.threads, "--threads"), (args.reps, "--reps"), (args.batch_windows, "--batch-windows")):
        bc.check_positive(value, flag)
    threads = args.threads or (1 if args.quick else 2)  # a smoke test on a busy CI machine: 1
    t0 = time.perf_counter()
    part = getattr(args, "part", "all")
    rows, ratios = [], []
    for label, size in (cfg["sizes"].items() if part in ("all", "encodings") else ()):
        base = {"size": size, "n_frames": cfg["n_frames"], "batch_windows": args.batch_windows}
        bc.progress(f"speed {label}: step times ({cfg['reps']} alternating steps per mode) ...")
        steps = bc.run_isolated(time_steps, {**base, "reps": cfg["reps"]}, threads=threads)
        mem = {}
        for mode in MODES:
            bc.progress(f"speed {label}: peak memory, {mode} ...")
            mem[mode] = bc.run_isolated(peak_memory, {**base, "mode": mode}, threads=threads)
        bc.progress(f"speed {label}: per-frame fit to convergence ...")
        conv = bc.run_isolated(converge, {**base, "max_steps": cfg["max_steps"]}, threads=threads)
        for mode in MODES:
            s = steps[mode]
            r = {"size": label, "mode": mode, **{k: v for k, v in s.items()}, **mem[mode],
                 "epoch_s": s["step_min_s"] * s["windows"] / s["windows_per_step"],
                 "converge_steps": conv["steps"], "loss_diff": steps["loss_diff"]}
            if mode == "per-frame":
                r.update(converge_s=conv["wall_s"], converge_cpu_s=conv["cpu_s"], converged=conv["converged"],
                         estimate=conv.get("estimate"))
            rows.append(r)
        pf, pw = rows[-2], rows[-1]
        # the same loss takes the same steps, each dearer by the ratio of the least-contended step times
        pw["converge_s"] = conv["wall_s"] * pw["step_min_s"] / pf["step_min_s"]
        ratios.append({"size": label, "step": pw["step_min_s"] / pf["step_min_s"],
                       "step_median": pw["step_median_s"] / pf["step_median_s"],
                       "step_cpu": pw["step_cpu_min_s"] / pf["step_cpu_min_s"], "epoch": pw["epoch_s"] / pf["epoch_s"],
                       "converge": pw["converge_s"] / pf["converge_s"],
                       "peak_rss": pw["peak_rss_mb"] / pf["peak_rss_mb"],
                       "rss_rise": pw["rss_rise_mb"] / pf["rss_rise_mb"] if pf["rss_rise_mb"] > 0 else math.nan})
    restart_rows = []
    for label, size in (cfg["sizes"].items() if part in ("all", "restarts") else ()):
        bc.progress(f"speed {label}: batched restarts {', '.join(map(str, cfg['restarts']))} ...")
        got = bc.run_isolated(time_restarts, {"size": size, "n_frames": cfg["n_frames"], "restarts": cfg["restarts"],
                                              "steps": cfg["restart_steps"], "rounds": cfg["rounds"]}, threads=threads)
        restart_rows += [{"size": label, **r} for r in got]
    answer = ANSWER_QUICK if args.quick else ANSWER
    answer_rows = []
    for i in range(answer["repeats"] if part in ("all", "answer") else 0):
        bc.progress(f"speed: one restart to the answer, repeat {i + 1} of {answer['repeats']} ...")
        answer_rows.append(bc.run_isolated(one_answer, answer, threads=threads))
    compile_task = {"restarts": 1, "windows": 500 if not args.quick else 20, "window": 20, "reps": 30 if not args.quick else 2}
    compiled = None
    if part == "compile":
        bc.progress("speed: torch.compile of the rollout (about a minute to compile) ...")
        compiled = bc.run_isolated(time_compile, compile_task, threads=threads)
    wall = time.perf_counter() - t0
    machine = bc.machine_info()
    if rows:
        print(table(rows))
        print()
    if restart_rows:
        print(restart_table(restart_rows))
        print()
    if answer_rows:
        print(answer_table(answer_rows, answer))
        print()
    if compiled is not None:
        print(compile_table(compiled, compile_task))
        print()
    for q in ratios:
        print(f"{q['size']}: per-window / per-frame = {q['step']:.1f}x per step (min; median {q['step_median']:.1f}x, "
              f"CPU {q['step_cpu']:.1f}x), {q['epoch']:.1f}x per epoch, {q['converge']:.1f}x to converge, "
              f"{q['peak_rss']:.2f}x peak RSS ({q['rss_rise']:.1f}x its rise)")
    for r in rows:
        if r["mode"] == "per-frame" and r.get("estimate"):
            e = r["estimate"]
            print(f"{r['size']} per-frame fit: g0 = {e['g0']:.4f}, g1 = {e['g1']:.4f} after {r['converge_steps']} "
                  f"steps ({'converged' if r['converged'] else 'step limit'}), {r['converge_s']:.1f} s")
    print(f"{threads} torch thread(s), {machine['cpus']} CPUs, load average {machine['load_avg']}: {wall:.0f} s wall")
    record = {"bench": "speed", "quick": bool(args.quick), "equation": EQUATION,
              "settings": {"n_frames": cfg["n_frames"], "sizes": {k: list(v) for k, v in cfg["sizes"].items()},
                           "reps": cfg["reps"], "threads": threads, "batch_windows": args.batch_windows,
                           "memory_steps": MEMORY_STEPS},
              "rows": rows, "ratios": ratios, "restart_rows": restart_rows, "answer_rows": answer_rows,
              "answer_settings": answer, "compile": compiled, "wall_s": wall, "machine": machine}
    path = bc.write_record(record, args.out, "speed")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
