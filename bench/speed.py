"""speed: per-frame against per-window encoding, time per step, per epoch and to a converged estimate.

fitode's trainer encodes every distinct frame of a batch once per step and gathers the windows
from that encoded sequence by index (per-frame). The official code of the paper encodes each
window's frames separately, so a frame is encoded once for every window that contains it
(per-window: about window-length times the encoder work). Per-window is run here through the
same trainer with its frame gather swapped for one that returns every window's frames in full
(frames[window_index]): the encoder sees W x L frames per step, everything else is identical,
so both modes compute the same loss and gradients (up to float rounding; the table's last
column checks the losses over the timed steps).

Video: the paper's intensity dataset (fitode.synth.paper_video, damped oscillator, 270 frames
at dt 0.2 s) at 50x50, and the same frames resized to 64x114 (what `fitode VIDEO` makes of a
480x270 video: short side 64). Equation text, one restart from the trainer's default start,
every TrainConfig default (full batch: one step is one pass over all windows, i.e. one epoch).

For each size and mode, in a fresh process with --threads torch threads (default 2):
- time per step: the median over the steps after the horizon warm-up (full 20-frame windows);
  per-frame from the fit below, per-window from a fit of --timing-steps steps (default: warm-up + 50);
- time per epoch: steps per pass over all windows (1 with the default full batch) x step time;
- time to a converged estimate: per-frame, a whole fit to the trainer's stopping rule, measured;
  per-window, estimated as that fit's number of steps, each costing what the per-window run
  measured for its horizon (the timed steps, then the full-window median): the same loss gives
  the same steps, and the per-window run to convergence would take many minutes;
- peak memory: the process's peak RSS, and its rise over the RSS before the fit.

    python bench/speed.py              # or: fitode bench speed
    python bench/speed.py --quick      # smoke test

Prints the table and the per-window / per-frame ratios; writes <out>/speed.json.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402

EQUATION = "z'' + g1*z' + g0*z = 0"
SIZES = {"50x50": (50, 50), "64x114": (64, 114)}
MODES = ("per-frame", "per-window")
FULL = {"n_frames": 270, "sizes": SIZES, "timing_steps": None, "max_steps": None}
QUICK = {"n_frames": 40, "sizes": {"16x28": (16, 28)}, "timing_steps": 8, "max_steps": 8}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=None)
    parser.add_argument("--threads", type=int, default=None, help="torch threads (default 2; --quick: 1)")
    parser.add_argument("--sizes", default=None, help="comma-separated HxW sizes (default 50x50,64x114)")
    parser.add_argument("--timing-steps", type=int, default=None,
                        help="steps of the timing fits (default: the horizon warm-up + 50)")
    parser.add_argument("--batch-windows", type=int, default=None,
                        help="windows per step (default: TrainConfig's, all of them)")


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


@contextmanager
def per_window_encoding():
    """Make the trainer encode every frame of every window (the official code's way)."""
    import torch

    import fitode.train.trainer as trainer

    original = trainer.distinct_frames
    calls = [0]

    def every_window_frame(index: torch.Tensor):
        calls[0] += 1
        flat = index.reshape(-1)
        return flat, torch.arange(flat.numel(), device=index.device).reshape(index.shape)

    trainer.distinct_frames = every_window_frame
    try:
        yield calls
    finally:
        trainer.distinct_frames = original


def measure(task: dict[str, Any]) -> dict[str, Any]:
    """One size and mode, in its own process: a timing fit (and, per-frame, a fit to convergence)."""
    import fitode
    from fitode.errors import FitodeError
    from fitode.train.trainer import TrainConfig
    from fitode.train.windows import Windows

    frames, dt = frames_for(tuple(task["size"]), task["n_frames"])
    defaults = TrainConfig()
    warmup = defaults.horizon_warmup
    steps = task["timing_steps"] or warmup + 50
    opts = {} if task["batch_windows"] is None else {"batch_windows": task["batch_windows"]}
    n_windows = Windows(len(frames), defaults.window).count
    per_step_windows = min(task["batch_windows"] or n_windows, n_windows)
    # one-time costs (torch's first ops, compiling the equation) must not count against either mode
    fitode.fit(frames, dt, eq=EQUATION, restarts=1, progress=False, max_steps=2)
    rss_before = bc.current_rss_mb()
    out: dict[str, Any] = {"size": task["label"], "mode": task["mode"], "frames": len(frames),
                           "pixels": int(frames.shape[1] * frames.shape[2]), "windows": n_windows,
                           "windows_per_step": per_step_windows, "threads": task["threads"],
                           "rss_before_mb": rss_before}

    def fit(max_steps: int, rec: bc.StepRecorder):
        return fitode.fit(frames, dt, eq=EQUATION, restarts=1, progress=False, callback=rec,
                          max_steps=max_steps, **opts)

    rec = bc.StepRecorder(names=("g0", "g1"))
    t0 = time.perf_counter()
    if task["mode"] == "per-window":
        with per_window_encoding() as calls:
            try:
                fit(steps, rec)
            except FitodeError as exc:
                out["error"] = str(exc)
        if calls[0] == 0:
            raise RuntimeError("the trainer no longer gathers windows through distinct_frames: "
                               "bench/speed.py cannot swap in per-window encoding; update it")
        out["frames_encoded_per_step"] = per_step_windows * defaults.window
    else:  # one fit to the stopping rule: its steps are timed too
        try:
            result = fit(task["max_steps"] or defaults.max_steps, rec)
            run = result.runs[0]
            out.update(converge_steps=run.steps, converged=run.converged, estimate=dict(run.final))
        except FitodeError as exc:
            out.update(converge_steps=len(rec.step), converged=False, error=str(exc))
        out["converge_s"] = time.perf_counter() - t0
        out["frames_encoded_per_step"] = len(frames) if task["batch_windows"] is None else None
    times = rec.step_times()
    full = times[warmup:] if len(times) > warmup + 5 else times  # quick settings never leave the warm-up
    out.update(timing_steps=len(times), step_s=float(np.median(full)),
               warmup_step_s=float(np.mean(times[:warmup])) if len(times) else math.nan,
               full_window_steps=len(full), epoch_s=float(np.median(full)) * n_windows / per_step_windows,
               losses=rec.loss, step_times=times.tolist())
    out["peak_rss_mb"] = bc.peak_rss_mb()
    out["rss_increase_mb"] = out["peak_rss_mb"] - rss_before
    return out


def estimate_converge_s(per_window: dict[str, Any], n_steps: int) -> float:
    """Seconds per-window encoding would need for n_steps: its measured steps, then its full-window median."""
    times = per_window["step_times"]
    if n_steps <= len(times):
        return float(sum(times[:n_steps]))
    return float(sum(times) + (n_steps - len(times)) * per_window["step_s"])


def loss_match(a: list[float], b: list[float]) -> float:
    """Largest relative difference between two loss histories over their common steps."""
    n = min(len(a), len(b))
    if n == 0:
        return math.nan
    x, y = np.asarray(a[:n]), np.asarray(b[:n])
    return float(np.max(np.abs(x - y) / np.maximum(np.abs(x), 1e-12)))


def table(rows: list[dict[str, Any]]) -> str:
    out = []
    for r in rows:
        out.append({"size": r["size"], "mode": r["mode"], "enc": bc.num(r.get("frames_encoded_per_step")),
                    "step": bc.num(1e3 * r["step_s"], 1), "warm": bc.num(1e3 * r["warmup_step_s"], 1),
                    "epoch": bc.num(r["epoch_s"], 3), "csteps": bc.num(r.get("converge_steps")),
                    "conv": bc.num(r.get("converge_s"), 1) + (" (est.)" if r["mode"] == "per-window" else ""),
                    "peak": bc.num(r["peak_rss_mb"], 0), "rise": bc.num(r["rss_increase_mb"], 0),
                    "match": bc.num(r.get("loss_match"), 2) if r["mode"] == "per-window" else ""})
    cols = [("size", "size"), ("encoding", "mode"), ("frames encoded/step", "enc"), ("ms/step", "step"),
            ("ms/step warm-up", "warm"), ("s/epoch", "epoch"), ("steps to conv", "csteps"),
            ("s to converge", "conv"), ("peak RSS MB", "peak"), ("RSS rise MB", "rise"), ("loss diff", "match")]
    return bc.format_table(out, cols, title="ms/step: median over full-window steps; warm-up: mean over the "
                                             "horizon warm-up; loss diff: max relative difference of the loss "
                                             "against per-frame over the timed steps")


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
    if args.timing_steps is not None:
        cfg["timing_steps"] = args.timing_steps
    if args.threads is None:  # a smoke test on a busy CI machine: two spinning threads per process only slow it
        args.threads = 1 if args.quick else 2
    for value, flag in ((args.threads, "--threads"), (args.timing_steps, "--timing-steps"),
                        (args.batch_windows, "--batch-windows")):
        bc.check_positive(value, flag)
    t0 = time.perf_counter()
    rows = []
    for label, size in cfg["sizes"].items():
        for mode in MODES:
            bc.progress(f"speed: {label} {mode} ...")
            r = bc.run_isolated(measure, {"label": label, "size": size, "mode": mode, "n_frames": cfg["n_frames"],
                                          "timing_steps": cfg["timing_steps"], "max_steps": cfg["max_steps"],
                                          "batch_windows": args.batch_windows, "threads": args.threads},
                                threads=args.threads)
            rows.append(r)
            bc.progress(f"  {1e3 * r['step_s']:.1f} ms/step, peak RSS {r['peak_rss_mb']:.0f} MB")
    ratios = []
    for label in cfg["sizes"]:
        pf = next(r for r in rows if r["size"] == label and r["mode"] == "per-frame")
        pw = next(r for r in rows if r["size"] == label and r["mode"] == "per-window")
        pw["loss_match"] = loss_match(pf["losses"], pw["losses"])
        pw["converge_steps"] = pf.get("converge_steps")
        pw["converge_s"] = estimate_converge_s(pw, int(pf.get("converge_steps") or 0))
        ratios.append({"size": label, "step": pw["step_s"] / pf["step_s"], "epoch": pw["epoch_s"] / pf["epoch_s"],
                       "converge": pw["converge_s"] / pf["converge_s"] if pf.get("converge_s") else math.nan,
                       "peak_rss": pw["peak_rss_mb"] / pf["peak_rss_mb"],
                       "rss_rise": pw["rss_increase_mb"] / pf["rss_increase_mb"] if pf["rss_increase_mb"] > 0 else math.nan})
    wall = time.perf_counter() - t0
    machine = bc.machine_info()
    print(table(rows))
    print()
    for q in ratios:
        print(f"{q['size']}: per-window / per-frame = {q['step']:.1f}x per step, {q['epoch']:.1f}x per epoch, "
              f"{q['converge']:.1f}x to converge (est.), {q['peak_rss']:.2f}x peak RSS ({q['rss_rise']:.1f}x its rise)")
    for r in rows:
        if r["mode"] == "per-frame" and "estimate" in r:
            e = r["estimate"]
            print(f"{r['size']} per-frame fit: g0 = {e['g0']:.4f}, g1 = {e['g1']:.4f} after {r['converge_steps']} steps "
                  f"({'converged' if r['converged'] else 'step limit'})")
    print(f"{args.threads} torch thread(s), {machine['cpus']} CPUs, load {machine['load_avg'][0]}: {wall:.0f} s wall")
    for r in rows:  # the JSON keeps the per-step times, not the loss series used for the check
        r.pop("losses", None)
    record = {"bench": "speed", "quick": bool(args.quick), "equation": EQUATION,
              "settings": {"n_frames": cfg["n_frames"], "sizes": {k: list(v) for k, v in cfg["sizes"].items()},
                           "timing_steps": cfg["timing_steps"], "threads": args.threads,
                           "batch_windows": args.batch_windows},
              "rows": rows, "ratios": ratios, "wall_s": wall, "machine": machine}
    path = bc.write_record(record, args.out, "speed")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
