"""Restarts run one after another (2 intra-op threads) against a pool of 2 single-threaded workers.

    python bench/restarts.py [--restarts 4] [--steps 200]

Prints wall time per setting and the speed-up; writes bench/out/restarts.json.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import torch

import fitode
from fitode import synth
from fitode.jsonio import write_json


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--restarts", type=int, default=4)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--size", type=int, default=50)
    args = ap.parse_args()
    v = synth.paper_video("intensity", size=args.size)
    rows = []
    for label, threads, workers in [("sequential, 2 threads", 2, 1), ("2 workers, 1 thread each", 1, 2)]:
        torch.set_num_threads(threads)
        t0 = time.perf_counter()
        res = fitode.fit(v.frames, v.dt, system="damped_oscillator", restarts=args.restarts, max_steps=args.steps,
                         min_steps=args.steps, workers=workers, progress=False)
        wall = time.perf_counter() - t0
        rows.append({"setting": label, "wall_s": wall, "g0": res.values["g0"], "g1": res.values["g1"]})
    base = rows[0]["wall_s"]
    print(f"{args.restarts} restarts x {args.steps} steps, intensity {args.size}x{args.size}, "
          f"{len(v.frames)} frames, load average {os.getloadavg()[0]:.1f}")
    print(f"{'setting':<28}{'wall s':>9}{'speed-up':>10}{'g0':>9}{'g1':>9}")
    for r in rows:
        print(f"{r['setting']:<28}{r['wall_s']:>9.1f}{base / r['wall_s']:>10.2f}{r['g0']:>9.4f}{r['g1']:>9.4f}")
    out = Path(__file__).resolve().parent / "out"
    out.mkdir(exist_ok=True)
    write_json({"args": vars(args), "rows": rows}, out / "restarts.json")


if __name__ == "__main__":
    main()
