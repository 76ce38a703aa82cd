"""oscillators: the coverage bench's damped-oscillator clips, both constants (g0 and the damping g1).

bench/coverage.py counts one constant per clip (g0 for the oscillator). A damping rate is what a
coarse integrator step biases first (one RK4 step a frame loses amplitude, which a fit reads as
damping: the paper's motion video's g1 0.25% low), so this prints both constants of the same fixed
list of clips (coverage.clip_list, the same seeds), each fitted as a user would (run_job, every
default), with the integrator's steps per frame the fit settled on.

    python bench/oscillators.py --clips 6      # the coverage bench's first 6 oscillator clips

Writes <out>/oscillators.json (every clip).
"""
from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402
import coverage  # noqa: E402


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=None)
    parser.add_argument("--clips", type=int, default=6, help="the first N oscillator clips (default 6)")
    parser.add_argument("--seed", type=int, default=0, help="the seed of the coverage bench's list (default 0)")


def fit_clip(task: dict[str, Any], quick: bool = False) -> dict[str, Any]:
    """One clip rendered as coverage renders it and fitted; both constants against the truth."""
    from fitode.pipeline import run_job
    from fitode.synth import render_equation, write_video

    video = render_equation("damped_oscillator", constants=task["constants"], y0={"z": 1.0},
                            n_frames=60 if quick else task["n_frames"], dt=task["dt"], size=task["size"],
                            seed=task["seed"], noise=task["noise"], mode="motion")
    tmp = Path(tempfile.mkdtemp(prefix="fitode-oscillators-"))
    try:
        t0 = time.perf_counter()
        report = run_job(write_video(video, tmp / "oscillator.mp4"), tmp / "run", system="damped_oscillator",
                         log=None, progress=False, plots=False).report
        row: dict[str, Any] = {"seed": task["seed"], "frames": task["n_frames"], "dt": task["dt"],
                               "omega_dt": math.sqrt(task["constants"]["g0"]) * task["dt"],
                               "substeps": report["settings"].get("substeps"), "fit_s": time.perf_counter() - t0}
        for name, truth in task["constants"].items():
            p = report["parameters"][name]
            iv = p.get("interval")
            row[name] = {"truth": truth, "estimate": p["value"], "off": p["value"] / truth - 1, "interval": iv,
                         "covered": bool(iv) and iv[0] <= truth <= iv[1], "verdict": p["verdict"]}
        return row
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def run(args: argparse.Namespace) -> int:
    tasks = [t for t in coverage.clip_list(["oscillator"], args.seed) if t["case"] == "oscillator"]
    rows = []
    print("seed  omega*dt  steps  g0 off    covered  verdict    g1 off    covered  verdict")
    for task in tasks[: (1 if args.quick else args.clips)]:
        row = fit_clip(task, args.quick)
        rows.append(row)
        cells = "  ".join(f"{100 * row[n]['off']:+.3f}%  {'yes' if row[n]['covered'] else 'NO':>7}  {row[n]['verdict']:<9}"
                          for n in ("g0", "g1"))
        print(f"{row['seed']:>4}  {row['omega_dt']:8.3f}  {row['substeps']:>5}  {cells}", flush=True)
    written = bc.write_record({"clips": rows}, args.out, "oscillators")
    covered = sum(r[n]["covered"] for r in rows for n in ("g0", "g1"))
    print(f"{covered} of {2 * len(rows)} intervals hold the truth; wrote {written}")
    return 0


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
