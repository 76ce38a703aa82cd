"""lightcurve: does fitode tell the camera's transfer curve (sRGB or linear light) right?

Lamps (fitode.synth.scene "led") with seeded random decay rates, noise and length, at five
sizes from 64x48 to 480x270, half stored sRGB-encoded and half as linear light, each written to
an mp4 and read the way `fitode VIDEO` reads it (fitode.pipeline.read_clip: gray, short side
64); then fitode.train.observe.light.choose_curve on the frames. No fitting: this counts the
curve choice alone, the step whose mistake costs a lamp's rate a factor of up to 2.4. A wrong
choice is the count that must stay 0; an untold one leaves the fit AMBIGUOUS (the rate's
interval then reaches down by the curve's power).

    python bench/lightcurve.py                 # or: fitode bench lightcurve (80 lamps, about 1 min)
    python bench/lightcurve.py --lamps 20 --seed 3

Prints a table per size and curve (told right, told wrong, untold) and writes
<out>/lightcurve.json with every lamp's two measures.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402

SIZES = ((48, 64), (72, 128), (135, 240), (180, 320), (270, 480))
CURVES = ("srgb", "linear")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=2)
    parser.add_argument("--lamps", type=int, default=80, help="how many lamps (default 80: 8 per size and curve)")
    parser.add_argument("--seed", type=int, default=0, help="the seed of the list of lamps (default 0)")
    parser.add_argument("--report", metavar="JSON", help="print the table of an earlier run's JSON and exit")


def lamp_list(n: int, seed: int) -> list[dict[str, Any]]:
    """Sizes and curves in turn, so the first N lamps cover each of them."""
    out = []
    for i in range(n):
        rng = np.random.default_rng([seed, i, 99])
        out.append({"index": i, "seed": seed * 100000 + i, "size": SIZES[i % len(SIZES)],
                    "curve": CURVES[(i // len(SIZES)) % len(CURVES)], "gamma": float(rng.uniform(0.5, 2.3)),
                    "noise": float(rng.uniform(0.5, 2.0)), "duration": float(rng.uniform(2.0, 3.0))})
    return out


def tell(task: dict[str, Any]) -> dict[str, Any]:
    """One lamp rendered, written, read and told; runs in a worker."""
    from fitode.pipeline import read_clip
    from fitode.synth import scene
    from fitode.synth.io import write_video
    from fitode.train.observe.light import choose_curve

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "lamp.mp4"
        write_video(scene("led", task["gamma"], seed=task["seed"], size=task["size"], noise=task["noise"],
                          duration=task["duration"], curve=task["curve"]), path)
        clip, _ = read_clip(path)
    choice = choose_curve(clip.frames)
    outcome = "untold" if not choice.told else ("right" if choice.light == task["curve"] else "wrong")
    return {**task, "size": list(task["size"]), "told": choice.light if choice.told else None,
            "outcome": outcome, "measures": choice.separation}


def print_report(record: dict[str, Any]) -> None:
    rows = []
    lamps = record["lamps"]
    for size in SIZES:
        for curve in CURVES:
            some = [r for r in lamps if tuple(r["size"]) == size and r["curve"] == curve]
            if some:
                rows.append({"size": f"{size[1]}x{size[0]}", "curve": curve, "lamps": len(some),
                             **{k: sum(r["outcome"] == k for r in some) for k in ("right", "wrong", "untold")}})
    rows.append({"size": "all", "curve": "", "lamps": len(lamps),
                 **{k: sum(r["outcome"] == k for r in lamps) for k in ("right", "wrong", "untold")}})
    print(bc.format_table(rows, [("size", "size"), ("stored", "curve"), ("lamps", "lamps"), ("told right", "right"),
                                 ("told wrong", "wrong"), ("untold", "untold")],
                          title=f"lightcurve: the camera's curve told from the frames ({bc.ran_on(record)})"))


def run(args: argparse.Namespace) -> int:
    if bc.reprinted(args, print_report):
        return 0
    bc.check_positive(args.lamps, "--lamps")
    t0 = time.perf_counter()
    tasks = lamp_list(args.lamps, args.seed)
    if args.quick:  # two lamps of each curve, tiny
        tasks = [t for i, t in enumerate(lamp_list(2 * len(SIZES), args.seed)) if i % len(SIZES) < 2]
        for t in tasks:
            t.update(size=(48, 64), duration=0.5)
    results = bc.run_pool(tell, tasks, args.workers)
    record = {"bench": "lightcurve", "quick": bool(args.quick), "machine": bc.machine_info(),
              "wall_s": time.perf_counter() - t0,
              "settings": {"lamps": len(tasks), "seed": args.seed, "workers": args.workers}, "lamps": results}
    return bc.report_and_write(record, args.out, "lightcurve", print_report)


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
