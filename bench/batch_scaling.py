"""Wall time of `fitode batch` on 15 small generated videos, local executor at 1 and 2 workers.

    python bench/batch_scaling.py [--workers 1,2] [--videos 15] [--steps 300] [--restarts 2]

Videos: the paper's damped oscillator z'' + g1*z' + g0*z = 0 rendered by fitode.synth in its
intensity mode (24x24 pixels, 80 frames at dt 0.2 s, a little noise), damping ratio as the
paper's (g1 = 0.08) and three frequencies (omega 1.5, 2, 2.5 rad/s), five videos each. Every worker count runs the whole batch from scratch into its own
folder (pool start-up included). Prints a table and writes bench/out/batch_scaling.json.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from fitode.batch import available_cpus, format_aggregate, run_batch
from fitode.jsonio import write_json
from fitode.synth import render_equation, write_video

EQ = "z'' + g1*z' + g0*z = 0"
ZETA = 0.04
SETTINGS = {f"omega-{w}": w for w in (1.5, 2.0, 2.5)}


def make_videos(folder: Path, n_videos: int) -> Path:
    rows = ["video,setting,true.g0,true.g1"]
    names = list(SETTINGS)
    for i in range(n_videos):
        setting = names[i % len(names)]
        omega = SETTINGS[setting]
        truth = {"g0": omega ** 2 + ZETA ** 2, "g1": 2 * ZETA}
        v = render_equation(EQ, constants=truth, y0={"z": 1.0}, n_frames=80, dt=0.2,
                            mode="intensity", size=24, seed=i, noise=0.02)
        path = write_video(v, folder / f"{setting}-{i:02d}.mp4")
        rows.append(f"{path.name},{setting},{truth['g0']},{truth['g1']}")
    manifest = folder / "videos.csv"
    manifest.write_text("\n".join(rows) + "\n")
    return manifest


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts (default 1,2)")
    ap.add_argument("--videos", type=int, default=15)
    ap.add_argument("--steps", type=int, default=300, help="max steps per restart (default 300)")
    ap.add_argument("--restarts", type=int, default=2)
    ap.add_argument("--out", default=str(Path(__file__).parent / "out"))
    args = ap.parse_args(argv)
    counts = [int(w) for w in args.workers.split(",")]
    defaults = {"eq": EQ, "fps": 5, "stride": 1, "restarts": args.restarts, "max_steps": args.steps,
                "min_steps": min(200, args.steps), "seed": 0}
    results = []
    with tempfile.TemporaryDirectory(prefix="fitode-batch-bench-") as tmp:
        manifest = make_videos(Path(tmp), args.videos)
        for w in counts:
            load_before = os.getloadavg()[0]
            t0 = time.perf_counter()
            res = run_batch(manifest, Path(tmp) / f"out-{w}", workers=w, defaults=defaults, log=None,
                            progress=sys.stderr.isatty())
            wall = time.perf_counter() - t0
            job_walls = [r.wall_s for r in res.rows if r.wall_s]
            job_cpu = [r.details.get("cpu_s", 0.0) for r in res.rows]
            results.append({"workers": w, "wall_s": round(wall, 2), "complete": res.counts["complete"],
                            "failed": res.counts["failed"], "job_wall_mean_s": round(sum(job_walls) / len(job_walls), 2),
                            "job_wall_sum_s": round(sum(job_walls), 2), "job_cpu_sum_s": round(sum(job_cpu), 2),
                            "aggregate": res.aggregate,
                            # other processes on the machine slow a pool down: a load above the
                            # core count makes the wall times say little about scaling
                            "load_avg_1min": [round(load_before, 2), round(os.getloadavg()[0], 2)]})
            print(f"workers={w}: {wall:.1f} s", flush=True)
            print(format_aggregate(res.aggregate), flush=True)
    base = results[0]["wall_s"]
    print()
    print(f"{args.videos} videos, {args.restarts} restarts x {args.steps} steps each; {available_cpus()} CPUs")
    print(f"{'workers':>7}  {'wall s':>7}  {'speed-up':>8}  {'jobs/min':>8}  {'mean job s':>10}  complete  "
          f"job CPU s  load before/after")
    for r in results:
        print(f"{r['workers']:>7}  {r['wall_s']:>7.1f}  {base / r['wall_s']:>8.2f}  "
              f"{60 * args.videos / r['wall_s']:>8.1f}  {r['job_wall_mean_s']:>10.2f}  {r['complete']:>5}/{args.videos}  "
              f"{r['job_cpu_sum_s']:>9.1f}  {r['load_avg_1min'][0]:.1f} / {r['load_avg_1min'][1]:.1f}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    record = {"bench": "batch_scaling", "videos": args.videos, "restarts": args.restarts, "max_steps": args.steps,
              "cpus": available_cpus(), "python": platform.python_version(), "machine": platform.machine(),
              "load_avg_1min": os.getloadavg()[0], "results": results}
    write_json(record, out / "batch_scaling.json")
    print(f"wrote {out / 'batch_scaling.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
