"""coverage: does fitode keep its word? The 95% intervals and the verdicts on generated clips, counted.

Every clip is generated with seeded random constants, noise, resolution and length, written to
an mp4 and fitted as a user would (fitode.pipeline.run_job, every default but the pictures, which
nobody looks at here: plots=False, the same numbers; the scene's shipped
equation file; bench/realistic.py's fit_video for the realistic scenes, calibrated with the true
state at two frames where the constant depends on the latent's units, none within 3 frames of a
bounce; the clips as they are filmed are scaled instead by the scene's ruler, as a user gives it: `--scale`
with each end clicked off by a pixel, realistic.clicked_ruler). The cases:

| case            | generator                                   | varied                                   |
| --------------- | ------------------------------------------- | ---------------------------------------- |
| oscillator      | fitode.synth render_equation, paper motion  | g0, g1, noise, size, length              |
| pendulum small  | realistic scene, 4-10 degree swing          | L, zeta, noise, size, length             |
| pendulum large  | realistic scene, 35-60 degree swing         | L, zeta, noise, size, length             |
| fall            | realistic scene free_fall, calibrated       | r0, noise, size                          |
| drain           | realistic scene torricelli, calibrated      | k, noise, size, length                   |
| led             | realistic scene, sRGB light                 | gamma, noise, size, length               |
| led-linear      | realistic scene, the light stored linear    | gamma, noise, size, length               |
| spring          | realistic scene, a ball crossing behind it  | w2, c, noise, size, length               |
| held-pendulum   | held_pendulum: a hand holds, lets go         | L, angle, hold, tremor, noise, size      |
| cart            | bumper_cart, its ruler clicked: 3-5 bounces | a, restitution, bounces, noise, size     |
| bounce          | bouncing_ball, its ruler clicked: 2-4 bounces | g, restitution, bounces, noise, size   |
| block-rest      | sliding_block at 240 fps, rests each end, its ruler clicked | alpha, rests, noise, size |
| throw           | throw at 240 fps, held, flying, at rest, its ruler clicked | g, angle, range, ball, rests, noise, size |
| puck            | sliding_puck: held, pushed by a hand, sliding to a stop by friction, its ruler clicked | a, push, slide, rests, fps, noise, size |

Per clip: the truth, the estimate, its 95% interval, its verdict. Printed: the coverage of the
95% intervals (how often they hold the truth), the false-trust rate (TRUSTED and outside its 99%
interval, the 95% one widened by 2.576 / 1.96, or more than 5% off) and the false-alarm rate
(within 2% of the truth and not TRUSTED). An estimate left in the latent's units (a calibration
that could not be applied: result.json's latent_units) has no interval in the truth's units: it
counts as a clip without an interval. The spring case runs where fitode.synth has the spring
scene (a can bouncing on a spring, swaying, a ball carried across behind it); without it the
bench says the case is missing. Not varied: the camera's angle (no generator has one).

    python bench/coverage.py                   # or: fitode bench coverage (112 clips: about 10 minutes on 2 cores)
    python bench/coverage.py --clips 6         # the first 6 clips of the same fixed list
    python bench/coverage.py --cases held-pendulum,cart,bounce,block-rest --clips 8   # clips as they are filmed
    python bench/coverage.py --quick           # smoke test: 2 tiny clips, 10 steps (numbers mean nothing)

Writes <out>/coverage.json (every clip).
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

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402
import realistic  # noqa: E402

# clips as they are filmed (train/pieces.py): drawn from a stream of their own, after the others, so that
# the list of the cases before them stays what it was
PIECES_CASES = ("held-pendulum", "cart", "bounce", "block-rest")
# drawn from a third stream, after the pieces, so that both lists before them stay what they were
LATER_CASES = ("throw",)
# and a fourth: a puck pushed by a hand, sliding until friction stops it
PUSHED_CASES = ("puck",)
CASES = ("oscillator", "pendulum-small", "pendulum-large", "fall", "drain", "led", "led-linear", "spring") + PIECES_CASES \
    + LATER_CASES + PUSHED_CASES
SPRING = {"system": "spring", "quantity": "w2", "unit": "1/s^2"}
SPECS = {"spring": SPRING, "held-pendulum": {"system": "pendulum", "quantity": "L", "unit": "m"},
         "cart": {"system": "incline_cart", "quantity": "a", "unit": "m/s^2"},
         "bounce": {"system": "throw", "quantity": "g", "unit": "m/s^2"},
         "throw": {"system": "throw", "quantity": "g", "unit": "m/s^2"},
         "puck": {"system": "incline_cart", "quantity": "a", "unit": "m/s^2"}}
PER_CASE = 8
Z99_OVER_Z95 = 2.5758 / 1.9600
TRUST_OFF = 0.05
RIGHT = 0.02
SIZES = ((135, 240), (180, 320), (270, 480))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=2)
    parser.add_argument("--clips", type=int, default=None, help=f"the first N clips of the list (default all, "
                        f"{PER_CASE * len(CASES)})")
    parser.add_argument("--cases", default=",".join(CASES), help=f"comma-separated subset of {', '.join(CASES)}")
    parser.add_argument("--seed", type=int, default=0, help="the seed of the list of clips (default 0)")
    parser.add_argument("--report", metavar="JSON", help="print the table of an earlier run's JSON and exit")


def clip_list(cases: list[str], seed: int, per_case: int = PER_CASE) -> list[dict[str, Any]]:
    """The fixed list of clips: one seeded draw of constants and conditions per clip. The single-stretch
    cases come first, interleaved so that their first N clips cover each of them, and are the same
    clips as before the pieces cases were added (`--clips 48` is the earlier list); the pieces cases
    (holds, bounces, rests) follow, interleaved among themselves, drawn from a seed of their own."""
    rng = np.random.default_rng(seed)
    cases = [c for c in cases if c not in missing_cases()]
    out = []
    for i in range(per_case):
        for case in [c for c in cases if c not in PIECES_CASES + LATER_CASES + PUSHED_CASES]:
            size = SIZES[int(rng.integers(len(SIZES)))]
            noise = float(rng.uniform(0.5, 2.0))
            task: dict[str, Any] = {"case": case, "seed": seed * 1000 + len(out), "train": {}, "keep": None,
                                    "calibrate": True}
            if case == "oscillator":
                w, zeta = rng.uniform(1.0, 3.0), rng.uniform(0.01, 0.08)
                task.update(constants={"g0": w * w + zeta * zeta, "g1": 2 * zeta}, quantity="g0",
                            n_frames=int(rng.integers(150, 300)), dt=float(rng.uniform(0.1, 0.2)),
                            size=int(rng.choice([40, 50, 64])), noise=0.02 * noise)
            else:
                scene, kwargs = _scene_case(case, rng)
                task.update(scene=scene, setting=kwargs.pop("setting"), scene_kwargs={
                    **kwargs, "size": size, "noise": noise})
                if case == "spring":
                    task["spec"] = SPRING
            out.append(task)
    # the clips as they are filmed, each family from a stream of its own (the lists before it stay
    # what they were): the pieces, then the throws, then the pushed pucks
    for key, base, kinds, draw in ((32, 500, PIECES_CASES, _pieces_case), (33, 800, LATER_CASES, _throw_case),
                                   (34, 900, PUSHED_CASES, _puck_case)):
        rng = np.random.default_rng([seed, key])
        for i in range(per_case):
            for j, case in enumerate(c for c in cases if c in kinds):
                size = SIZES[int(rng.integers(len(SIZES)))]
                scene, kwargs = draw(case, rng)
                task = {"case": case, "seed": seed * 1000 + base + len(kinds) * i + j, "train": {}, "keep": None,
                        "calibrate": True, "ruler": True, "scene": scene, "setting": kwargs.pop("setting"),
                        "scene_kwargs": {**kwargs, "size": size, "noise": float(rng.uniform(0.5, 2.0))}}
                if case in SPECS:
                    task["spec"] = SPECS[case]
                out.append(task)
    return out


def _pieces_case(case: str, rng) -> tuple[str, dict[str, Any]]:
    if case == "held-pendulum":
        return "held_pendulum", {"setting": float(rng.uniform(0.3, 1.5)), "theta0_deg": float(rng.uniform(35, 60)),
                                 "hold": float(rng.uniform(0.8, 2.0)), "duration": float(rng.uniform(5.0, 8.0))}
    if case == "cart":
        return "bumper_cart", {"setting": float(rng.uniform(0.2, 1.2)), "bounces": int(rng.integers(3, 6))}
    if case == "bounce":
        return "bouncing_ball", {"setting": float(rng.uniform(5.0, 20.0)), "bounces": int(rng.integers(2, 5))}
    # a block that rests, slides and stops, filmed at 240 fps
    return "sliding_block", {"setting": float(rng.uniform(20.0, 35.0)), "rest_before": float(rng.uniform(0.2, 0.5)),
                             "rest_after": float(rng.uniform(0.2, 0.5)), "fps": 240.0}


def _throw_case(case: str, rng) -> tuple[str, dict[str, Any]]:
    # a ball 3 to 7 cm across thrown at 15-75 degrees over 0.6-3 m, filmed at 240 fps from its hold in
    # the hand to its rest where it lands, the frames stored at 240
    return "throw", {"angle": float(rng.uniform(15.0, 75.0)), "range": float(rng.uniform(0.6, 3.0)),
                     "radius": float(rng.uniform(0.015, 0.035)), "rest_before": float(rng.uniform(0.05, 0.5)),
                     "rest_after": float(rng.uniform(0.05, 0.5)), "fps": 240.0, "setting": float(rng.uniform(1.6, 25.0))}


def _puck_case(case: str, rng) -> tuple[str, dict[str, Any]]:
    # mu 0.03-0.4, pushed over 0.05-0.25 s, sliding 0.3-0.9 m, filmed at 60, 120 or 240 fps
    return "sliding_puck", {"rest_before": float(rng.uniform(0.1, 0.5)), "push_s": float(rng.uniform(0.05, 0.25)),
                            "slide": float(rng.uniform(0.3, 0.9)), "rest_after": float(rng.uniform(0.2, 0.8)),
                            "fps": float(rng.choice([60.0, 120.0, 240.0])), "setting": float(rng.uniform(0.3, 4.0))}


def missing_cases() -> list[str]:
    """The cases whose generator this checkout lacks (the spring scene lands with another change)."""
    from fitode.synth import SCENES
    return [] if "spring" in SCENES else ["spring"]


def _scene_case(case: str, rng) -> tuple[str, dict[str, Any]]:
    if case == "spring":
        return "spring", {"setting": float(rng.uniform(10.0, 35.0)), "c": float(rng.uniform(0.03, 0.15)),
                          "duration": float(rng.uniform(6.0, 12.0))}
    if case.startswith("pendulum"):
        swing = rng.uniform(4, 10) if case == "pendulum-small" else rng.uniform(35, 60)
        return "pendulum", {"setting": float(rng.uniform(0.3, 1.5)), "theta0_deg": float(swing),
                            "zeta": float(rng.uniform(0.02, 0.1)), "duration": float(rng.uniform(3.0, 6.0))}
    if case == "fall":
        return "free_fall", {"setting": float(rng.uniform(0.03, 0.1))}
    if case == "drain":
        return "torricelli", {"setting": float(rng.uniform(0.009, 0.017)), "duration": float(rng.uniform(4.0, 6.0))}
    kwargs = {"setting": float(rng.uniform(0.5, 2.3)), "duration": float(rng.uniform(2.0, 3.0))}
    if case == "led-linear":  # a scientific camera: the light stored linear, not sRGB
        kwargs["curve"] = "linear"
    return "led", kwargs


def fit_case(task: dict[str, Any]) -> dict[str, Any]:
    """One clip rendered and fitted; runs in a worker."""
    if "scene" in task:
        out = realistic.fit_video(task)
    else:
        out = _fit_oscillator(task)
    out["case"] = task["case"]
    return out


def _fit_oscillator(task: dict[str, Any]) -> dict[str, Any]:
    from fitode.errors import FitodeError
    from fitode.pipeline import run_job
    from fitode.synth import render_equation, write_video

    q = task["quantity"]
    out: dict[str, Any] = {"scene": "oscillator", "setting": task["constants"][q], "seed": task["seed"], "quantity": q,
                           "truth": task["constants"][q]}
    video = render_equation("damped_oscillator", constants=task["constants"], y0={"z": 1.0},
                            n_frames=task["n_frames"], dt=task["dt"], size=task["size"], seed=task["seed"],
                            noise=task["noise"], mode="motion")
    tmp = Path(tempfile.mkdtemp(prefix="fitode-coverage-"))
    try:
        path = write_video(video, tmp / "oscillator.mp4")
        t0 = time.perf_counter()
        try:
            outcome = run_job(path, tmp / "run", system="damped_oscillator", log=None, progress=False, plots=False,
                             **task["train"])
        except FitodeError as exc:
            out.update(status="failed", error=str(exc), estimate=math.nan)
            return out
        p = outcome.report["parameters"][q]
        out.update(status=outcome.report.get("status"), estimate=p["value"], interval=p.get("interval"),
                   latent_units=bool(p.get("latent_units")),
                   verdict=p.get("verdict"), reason=p.get("verdict_reason"), fit_s=time.perf_counter() - t0)
        return out
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def judge(v: dict[str, Any]) -> dict[str, Any]:
    """One clip's counts: covered (by the 95% interval), false trust, false alarm. An interval in
    the latent's units is none in the truth's."""
    truth, est, verdict = v.get("truth"), v.get("estimate"), v.get("verdict")
    iv = None if v.get("latent_units") else v.get("interval")
    off = abs(est - truth) / abs(truth) if est is not None and truth and math.isfinite(est) else math.inf
    covered = bool(iv) and iv[0] <= truth <= iv[1]
    inside99 = False
    if iv:
        lo, hi = est - (est - iv[0]) * Z99_OVER_Z95, est + (iv[1] - est) * Z99_OVER_Z95
        inside99 = lo <= truth <= hi
    trusted = verdict == "trusted"
    return {"off": off, "covered": covered, "has_interval": bool(iv),
            "false_trust": trusted and (not inside99 or off > TRUST_OFF),
            "false_alarm": off <= RIGHT and not trusted}


def summary(videos: list[dict[str, Any]]) -> dict[str, Any]:
    judged = [judge(v) for v in videos]
    n = len(judged)
    right = [j for j in judged if j["off"] <= RIGHT]
    trusted = [v for v in videos if v.get("verdict") == "trusted"]
    return {"clips": n, "covered": sum(j["covered"] for j in judged),
            "with_interval": sum(j["has_interval"] for j in judged),
            "trusted": len(trusted), "false_trust": sum(j["false_trust"] for j in judged),
            "right": len(right), "false_alarm": sum(j["false_alarm"] for j in judged)}


def print_report(record: dict[str, Any]) -> None:
    rows = []
    for v in record["videos"]:
        j = judge(v)
        iv = v.get("interval")
        rows.append({"case": v["case"], "q": v.get("quantity", ""), "truth": f"{v['truth']:.5g}",
                     "est": "nan" if v.get("estimate") is None else f"{v['estimate']:.5g}",
                     "iv": (f"[{iv[0]:.5g}, {iv[1]:.5g}]" + (" latent units" if v.get("latent_units") else ""))
                     if iv else "-", "off": bc.pct(j["off"], 2, signed=False),
                     "cov": "yes" if j["covered"] else "no", "verdict": v.get("verdict") or v.get("status", ""),
                     "flag": "FALSE TRUST" if j["false_trust"] else "false alarm" if j["false_alarm"] else ""})
    cols = [("case", "case"), ("constant", "q"), ("truth", "truth"), ("estimate", "est"), ("95% interval", "iv"),
            ("off", "off"), ("covered", "cov"), ("verdict", "verdict"), ("", "flag")]
    print(bc.format_table(rows, cols, title="coverage: every generated clip"))
    s = summary(record["videos"])
    n = max(s["clips"], 1)
    print(f"\n95% intervals cover the truth in {s['covered']} of {s['clips']} clips ({100 * s['covered'] / n:.0f}%; "
          f"{s['with_interval']} have an interval in the truth's units; of those, "
          f"{100 * s['covered'] / max(s['with_interval'], 1):.0f}% cover it)")
    print(f"false trust: {s['false_trust']} of {s['clips']} ({100 * s['false_trust'] / n:.0f}%; TRUSTED in "
          f"{s['trusted']}, and outside its 99% interval or more than {TRUST_OFF:.0%} off)")
    print(f"false alarm: {s['false_alarm']} of {s['right']} estimates within {RIGHT:.0%} not TRUSTED")
    if record["settings"].get("missing"):
        print(f"missing: {', '.join(record['settings']['missing'])} (no such scene in fitode.synth on this checkout)")
    print(f"{bc.ran_on(record)}")


def run(args: argparse.Namespace) -> int:
    if bc.reprinted(args, print_report):
        return 0
    cases = bc.pick(args.cases, list(CASES), "--cases")
    tasks = clip_list(cases, args.seed)
    if args.quick:
        tasks = [t for t in tasks if t["case"] in ("oscillator", "led")][:2]
        for t in tasks:
            t["train"] = {"max_steps": 10, "restarts": 1}
            if "scene" in t:
                t["scene_kwargs"].update(size=(36, 64), duration=1.5)
                t["calibrate"] = False
            else:
                t.update(n_frames=60, size=32)
    elif args.clips is not None:
        bc.check_positive(args.clips, "--clips")
        tasks = tasks[: args.clips]
    missing = [c for c in cases if c in missing_cases()]
    if missing:
        bc.progress(f"coverage: missing case{'s' if len(missing) > 1 else ''} {', '.join(missing)} (no scene in "
                    "fitode.synth here)")
    bc.progress(f"coverage: {len(tasks)} clips on {args.workers} worker(s)")
    t0 = time.perf_counter()
    results = bc.run_pool(fit_case, tasks, args.workers, on_done=lambda i, v: bc.progress(
        f"  clip {i + 1} of {len(tasks)}, {v['case']}: {v.get('quantity')} = {v.get('estimate', math.nan):.5g} "
        f"(truth {v['truth']:.5g}), 95% {v.get('interval')}, {v.get('verdict')}"))
    record = {"bench": "coverage", "quick": bool(args.quick), "settings": {"cases": cases, "missing": missing,
              "seed": args.seed,
              "clips": len(tasks), "workers": args.workers}, "summary": summary(results), "videos": results,
              "wall_s": time.perf_counter() - t0, "machine": bc.machine_info()}
    return bc.report_and_write(record, args.out, "coverage", print_report)


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
