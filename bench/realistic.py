"""realistic: the five realistic scenes, the paper's quantity per setting, beside the truth and the paper's numbers.

Scenes from fitode.synth.scene, modelled on the paper's real dataset (Delfys75): 480x270 RGB at
60 fps, textured backgrounds, shading, sensor noise, blur and JPEG; each setting of each scene
rendered --videos times (default 5) with seeds 0..N-1 (different initial conditions, textures
and noise). Every video is written to an mp4 and fitted the way a user would:
`fitode.pipeline.run_job` (the `fitode VIDEO` job: default preprocessing, gray, short side 64
so 64x114, automatic stride, every TrainConfig default, 3 restarts), with the scene's shipped
equation file:

| scene         | equation (file)                         | quantity | calibration               |
| ------------- | --------------------------------------- | -------- | ------------------------- |
| pendulum      | theta'' = -g/L sin(theta) - zeta theta' | L        | theta at two times        |
| torricelli    | h' = -k sqrt(h)                         | k        | h at two times            |
| sliding_block | s'' = a (see below)                     | a        | s at two times            |
| led           | I' = -gamma (I - c), --encoder linear    | gamma    | none (scale-free)         |
| free_fall     | d'' = g                                 | g        | d at two times            |

Calibration: where fitode.eqparse.analyse says the quantity depends on the latent's scale
(k, a, g; and L, scale-free only at small amplitude), the fit is given `calibrate=` with the
true state at the two kept frames where it is largest and smallest (taken from the generator's
ground truth, as a user would measure two positions with a ruler); the table says which. The
uncalibrated estimate (latent units) is shown beside it.

sliding_block: the shipped file's x'' = g (sin(alpha) - mu cos(alpha)) fixes only that
combination (the identifiability report says so), so the bench fits the measurable acceleration
directly, s'' = a, the paper's reported quantity (s along the incline: a state named x would be read
along the image's horizontal, a cos(alpha), as a user who writes x asks). led: `fitode check` advises the linear
encoder for a first-order linear equation (an MLP can report I**p, which decays at p*gamma), so
the bench passes encoder="linear"; every other option is TrainConfig's default.

Paper numbers: the paper's estimates on its real videos (pendulum L 0.51 / 1.07 / 1.30 for
0.45 / 0.90 / 1.50 m; Torricelli k 0.0094 / 0.0132 / 0.0167; sliding a 1.29 / 2.70 / 3.44 for
1.441 / 2.300 / 3.141 m/s^2; LED gamma 2.24 / 0.97 / 0.41; free fall g 15.0 / 9.51 / 10.22 for
9.8), one row per setting, in the order of SCENES[...].settings.

    python bench/realistic.py                  # or: fitode bench realistic (about 70 min on 2 cores)
    python bench/realistic.py --videos 1       # one video per setting (measured 803 s on 2 busy cores)
    python bench/realistic.py --quick          # smoke test

Prints the table; writes <out>/realistic.json (every video: estimate, raw estimate,
calibration, runs, wall time). --keep also keeps each video and its run folder, with its
pictures, under <out>/realistic/ (without it no run draws pictures: the same numbers, sooner).
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

G = 9.80665
# scene -> how it is fitted and what is reported
SPEC: dict[str, dict[str, Any]] = {
    "pendulum": {"system": "pendulum", "quantity": "L", "unit": "m"},
    "torricelli": {"system": "torricelli", "quantity": "k", "unit": "m^0.5/s"},
    "sliding_block": {"eq": "s'' = a", "quantity": "a", "unit": "m/s^2"},
    # `fitode check --system led_decay`: "a nonlinear encoder (mlp, cnn) can report any rate; fit it
    # with --encoder linear" -- the bench takes the tool's advice, as a user would
    "led": {"system": "led_decay", "quantity": "gamma", "unit": "1/s", "train": {"encoder": "linear"}},
    "free_fall": {"system": "free_fall_scale", "quantity": "g", "unit": "m/s^2"},
}
# the paper's estimates on its real videos, and the truth it compared them with (None: not
# given; our scene's setting is then the reference)
PAPER = {
    "pendulum": ((0.51, 1.07, 1.30), (0.45, 0.90, 1.50)),
    "torricelli": ((0.0094, 0.0132, 0.0167), None),
    "sliding_block": ((1.29, 2.70, 3.44), (1.441, 2.300, 3.141)),
    "led": ((2.24, 0.97, 0.41), None),
    "free_fall": ((15.0, 9.51, 10.22), (9.8, 9.8, 9.8)),
}
QUICK_SCENE = {"size": (36, 64)}
QUICK_DURATION = {"pendulum": 1.5, "torricelli": 1.5, "led": 1.5}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=2)
    parser.add_argument("--videos", type=int, default=None, help="videos per setting (default 5; --quick 1)")
    parser.add_argument("--scenes", default=",".join(SPEC), help=f"comma-separated subset of {', '.join(SPEC)}")
    parser.add_argument("--max-steps", type=int, default=None, help="override TrainConfig.max_steps (default: TrainConfig's)")
    parser.add_argument("--restarts", type=int, default=None, help="override TrainConfig.restarts (default: TrainConfig's)")
    parser.add_argument("--seed", type=int, default=0, help="first video seed (default 0)")
    parser.add_argument("--observe", default=None, metavar="MODEL",
                        help="the observation model for every scene run (default: each scene's own: its equation "
                             "file's or auto), e.g. --scenes pendulum --observe position")
    parser.add_argument("--no-calibrate", action="store_true",
                        help="report every quantity uncalibrated (--quick does: the calibration re-fit takes tens of seconds)")
    parser.add_argument("--keep", action="store_true", help="keep every video and run folder under <out>/realistic/")
    parser.add_argument("--report", metavar="JSON", help="print the table of an earlier run's JSON and exit")


def truth_of(scene_name: str, video) -> float:
    q = SPEC[scene_name]["quantity"]
    if scene_name == "sliding_block":
        return float(video.meta["physical"]["a"])
    if scene_name == "free_fall":
        return float(video.meta["physical"]["g"])
    return float(video.truth[q])


IMPACT_FRAMES = 3


def clicked_ruler(ruler: dict[str, Any], rng: np.random.Generator) -> str:
    """The scene's ruler as a user gives it: each end clicked off by N(0, 1) pixel along each axis,
    the error fitode's --scale assumes (fitode.scale.END_STD), so that its share of the interval is
    tried, not only granted."""
    from fitode.scale import END_STD

    (x1, y1), (x2, y2) = (np.asarray(ruler[k], dtype=float) + rng.normal(0.0, END_STD, 2) for k in ("p1", "p2"))
    return f"{x1:.2f},{y1:.2f},{x2:.2f},{y2:.2f}={ruler['metres']:g}"


def calibration_points(clip, video, state: str) -> str:
    """The true state at the kept frames where it is largest and smallest, as --calibrate text;
    never within IMPACT_FRAMES of a bounce (the state's velocity jumping between two frames): the
    smallest height of a bouncing ball is at its bounce, where the frame shows it squeezed into
    the floor's row and the tracker's centre misses the true one by pixels (g +4% on a small clip)."""
    idx = np.asarray(clip.frame_indices)
    idx = idx[idx < len(video.latent)]
    names = list(getattr(video, "state_names", ()) or ())
    if f"{state}'" in names and video.state is not None:
        v = np.asarray(video.state)[:, names.index(f"{state}'")]
        step = np.abs(np.diff(v))
        jumps = np.flatnonzero(step > 10 * max(float(np.median(step)), 1e-12))
        near = np.zeros(len(v), dtype=bool)
        for j in jumps:
            near[max(j - IMPACT_FRAMES + 1, 0):j + IMPACT_FRAMES + 1] = True
        if (~near[idx]).sum() >= 2:
            idx = idx[~near[idx]]
    col = list(video.latent_names).index(state)
    values = video.latent[idx, col]
    hi, lo = idx[int(np.argmax(values))], idx[int(np.argmin(values))]
    pts = sorted({int(hi), int(lo)})
    return "; ".join(f"{state}({i / clip.fps:.9g})={video.latent[i, col]:.9g}" for i in pts)


def needs_calibration(ode, quantity: str) -> tuple[bool, str]:
    from fitode.eqparse import analyse

    for c in analyse(ode).constants:
        if c.name == quantity:
            return c.scale != "free", c.scale
    return False, "unknown"


def fit_video(task: dict[str, Any]) -> dict[str, Any]:
    """Render one scene video, write it as mp4, fit it with the pipeline; runs in a worker."""
    from fitode.eqfile import resolve
    from fitode.errors import FitodeError
    from fitode.pipeline import run_job
    from fitode.synth import scene, write_video
    from fitode.video import read_video

    name, setting, seed = task["scene"], task["setting"], task["seed"]
    spec = task.get("spec") or SPEC[name]  # another bench's scene (coverage's spring) brings its own
    out: dict[str, Any] = {"scene": name, "setting": setting, "seed": seed, "quantity": spec["quantity"],
                           "options": {**spec.get("train", {}), **task["train"]}}
    t0 = time.perf_counter()
    video = scene(name, setting, seed=seed, **task["scene_kwargs"])
    out["render_s"] = time.perf_counter() - t0
    out["truth"] = truth_of(name, video) if name in SPEC else float(video.truth[spec["quantity"]])
    keep = Path(task["keep"]) if task["keep"] else None
    tmp = tempfile.mkdtemp(prefix="fitode-realistic-")
    folder = keep if keep is not None else Path(tmp)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = write_video(video, folder / f"{name}-{setting:g}-{seed}.mp4")
        eq_args = {"eq": spec["eq"]} if "eq" in spec else {"system": spec["system"]}
        ode, _ = resolve(**eq_args)
        calibrate, scale = needs_calibration(ode, spec["quantity"])
        out["scale"] = scale
        points, stick = None, None
        ruler = (video.meta.get("physical") or {}).get("ruler")
        if calibrate and task.get("calibrate", True):
            if task.get("ruler") and ruler:
                stick = clicked_ruler(ruler, np.random.default_rng([seed, 41]))
            else:
                clip = read_video(path)  # the same defaults as run_video, to pick frames it keeps
                points = calibration_points(clip, video, ode.states[0])
        out["calibration"] = points or (stick and f"--scale {stick}")
        t1 = time.perf_counter()
        try:
            outcome = run_job(path, folder / "run", calibrate=points, scale=stick, log=None, progress=False,
                              plots=keep is not None,  # pictures only where the run folder is kept to look at
                              **eq_args, **{**spec.get("train", {}), **task["train"]})
        except FitodeError as exc:
            out.update(status="failed", error=str(exc), estimate=math.nan, raw=math.nan, fit_s=time.perf_counter() - t1)
            return out
        out["fit_s"] = time.perf_counter() - t1
        rep, res = outcome.report, outcome.result
        q = spec["quantity"]
        out.update(status=rep.get("status"), estimate=rep["parameters"][q]["value"],
                   std_restarts=rep["parameters"][q]["std"], raw=res.parameters[q].latent_value if res.parameters[q].calibrated else res.parameters[q].value,
                   calibrated=bool(rep["parameters"][q].get("calibrated")),
                   latent_units=bool(rep["parameters"][q].get("latent_units")),
                   frames=int(len(res.time)), dt=float(res.dt), stride=rep.get("input", {}).get("stride"),
                   runs=[{"init": r.init, "final": r.final, "steps": r.steps, "converged": r.converged,
                          "status": r.status, "loss": r.loss, "wall_s": r.wall_s} for r in res.runs],
                   selected=list(res.selected), warnings=list(rep.get("warnings", [])),
                   verdict=rep["parameters"][q].get("verdict"), interval=rep["parameters"][q].get("interval"),
                   reason=rep["parameters"][q].get("verdict_reason"),
                   observation=res.meta["plan"]["observation"]["value"])
        return out
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def aggregate(videos: list[dict[str, Any]]) -> list[dict[str, Any]]:
    rows = []
    for name in SPEC:
        mine = [v for v in videos if v["scene"] == name]
        settings = list(dict.fromkeys(v["setting"] for v in mine))
        from fitode.synth import SCENES
        order = list(SCENES[name].settings)
        for setting in settings:
            vs = [v for v in mine if v["setting"] == setting]
            truth = float(np.mean([v["truth"] for v in vs]))
            mean, std, n = bc.mean_std(v.get("estimate") for v in vs)
            raw_mean, raw_std, _ = bc.mean_std(v.get("raw") for v in vs)
            paper = paper_truth = None
            if setting in order:
                k = order.index(setting)
                paper = PAPER[name][0][k]
                paper_truth = PAPER[name][1][k] if PAPER[name][1] else truth
            runs = [r for v in vs for r in v.get("runs", [])]
            rows.append({"scene": name, "quantity": SPEC[name]["quantity"], "unit": SPEC[name]["unit"],
                         "setting": setting, "setting_name": SCENES[name].setting, "truth": truth,
                         "mean": mean, "std": std, "n": n, "videos": len(vs), "rel_err": bc.rel_err(mean, truth),
                         "mean_abs_rel_err": bc.mean_std(abs(bc.rel_err(v.get("estimate"), v["truth"])) for v in vs)[0],
                         "raw_mean": raw_mean, "raw_std": raw_std,
                         "calibrated": any(v.get("calibration") for v in vs),
                         "needs_calibration": any(v.get("scale") not in (None, "free") for v in vs),
                         "scale": vs[0].get("scale"), "options": vs[0].get("options", {}), "paper": paper, "paper_truth": paper_truth,
                         "paper_rel_err": bc.rel_err(paper, paper_truth) if paper is not None else math.nan,
                         "runs_converged": sum(bool(r["converged"]) for r in runs), "runs": len(runs),
                         "failed_videos": sum(v.get("status") not in ("complete",) for v in vs),
                         "fit_s_mean": bc.mean_std(v.get("fit_s") for v in vs)[0],
                         "verdicts": [v.get("verdict") or "none" for v in vs],
                         "observation": vs[0].get("observation")})
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    out = []
    for r in rows:
        d = 4 if abs(r["truth"]) < 0.1 else 3
        out.append({"scene": r["scene"], "q": f"{r['quantity']} [{r['unit']}]",
                    "opt": " ".join(f"{k}={v}" for k, v in r.get("options", {}).items()) or "defaults",
                    "set": f"{r['setting_name']}={r['setting']:g}", "truth": f"{r['truth']:.{d}f}",
                    "est": bc.pm(r["mean"], r["std"], d) + f" ({r['n']})", "err": bc.pct(r["rel_err"], 1),
                    "paper": "-" if r["paper"] is None else f"{r['paper']:g}"
                    + (f" (of {r['paper_truth']:g})" if r["paper_truth"] is not None and abs(r["paper_truth"] - r["truth"]) > 1e-9 else ""),
                    "perr": bc.pct(r["paper_rel_err"], 1),
                    "cal": "2 points of the true state" if r["calibrated"] else
                    ("none: LATENT UNITS" if r.get("needs_calibration") else "none (scale-free)"),
                    "raw": bc.pm(r["raw_mean"], r["raw_std"], d) if r["calibrated"] else "",
                    "conv": f"{r['runs_converged']}/{r['runs']}", "wall": bc.num(r["fit_s_mean"], 0),
                    "obs": r.get("observation") or "", "verdicts": _verdicts(r.get("verdicts", []))})
    cols = [("scene", "scene"), ("quantity", "q"), ("options", "opt"), ("setting", "set"), ("truth", "truth"),
            ("fitode mean +- std (videos)", "est"), ("err", "err"), ("paper (real data)", "paper"),
            ("paper err", "perr"), ("calibration", "cal"), ("uncalibrated (latent units)", "raw"),
            ("restarts converged", "conv"), ("observation", "obs"), ("verdicts", "verdicts"), ("s/video", "wall")]
    return bc.format_table(out, cols, title="err: relative error of the mean; paper err: the paper's estimate against "
                                             "its own truth where the issue gives it, else against this setting")


def _verdicts(verdicts: list[str]) -> str:
    """'2 trusted' or '1 trusted, 1 ambiguous': how many videos got which verdict."""
    counts = {v: verdicts.count(v) for v in dict.fromkeys(verdicts)}
    return ", ".join(f"{n} {v}" for v, n in counts.items())


def print_report(record: dict[str, Any]) -> None:
    print(table(aggregate(record["videos"])))  # from the videos: --report applies today's table to an old record
    failed = [v for v in record["videos"] if v.get("status") != "complete"]
    for v in failed:
        print(f"  {v['scene']} {v['setting']:g} seed {v['seed']}: {v.get('status')}: {v.get('error')}")
    s = record["settings"]
    print(f"\n{len(record['videos'])} videos ({s['videos']} per setting), TrainConfig defaults but the options "
          f"column, {s['workers']} worker(s), {bc.ran_on(record)}")


def run(args: argparse.Namespace) -> int:
    from fitode.synth import SCENES

    if bc.reprinted(args, print_report):
        return 0
    scenes = bc.pick(args.scenes, list(SPEC), "--scenes")
    videos = args.videos if args.videos is not None else (1 if args.quick else 5)
    for value, flag in ((videos, "--videos"), (args.workers, "--workers"), (args.max_steps, "--max-steps"),
                        (args.restarts, "--restarts")):
        bc.check_positive(value, flag)
    train: dict[str, Any] = {}
    if args.quick:
        train = {"max_steps": 10, "restarts": 1}
    if args.max_steps is not None:
        train["max_steps"] = args.max_steps
    if args.restarts is not None:
        train["restarts"] = args.restarts
    if args.observe is not None:
        from fitode.train.config import OBSERVE_CHOICES
        if args.observe not in OBSERVE_CHOICES:
            raise SystemExit(f"realistic: error: --observe must be one of {', '.join(OBSERVE_CHOICES)}")
        train["observe"] = args.observe
    keep_root = Path(args.out) / "realistic" if args.keep else None
    calibrate = not (args.quick or args.no_calibrate)
    tasks = []
    for name in scenes:
        info = SCENES[name]
        settings = [info.settings[len(info.settings) // 2]] if args.quick else list(info.settings)
        kwargs: dict[str, Any] = {}
        if args.quick:
            kwargs = dict(QUICK_SCENE)
            if name in QUICK_DURATION:
                kwargs["duration"] = QUICK_DURATION[name]
        for setting in settings:
            for i in range(videos):
                seed = args.seed + i
                keep = str(keep_root / f"{name}-{setting:g}-{seed}") if keep_root else None
                tasks.append({"scene": name, "setting": float(setting), "seed": seed, "scene_kwargs": kwargs,
                              "train": train, "keep": keep, "calibrate": calibrate})
    bc.progress(f"realistic: {len(tasks)} videos on {args.workers} worker(s)")
    t0 = time.perf_counter()
    count = [0]

    def done(i, v):
        count[0] += 1
        bc.progress(f"  [{count[0]}/{len(tasks)}] {v['scene']} {v['setting']:g} seed {v['seed']}: "
                    f"{v['quantity']} = {v.get('estimate', math.nan):.5g} (truth {v['truth']:.5g}) "
                    f"{v.get('status')} {v.get('fit_s', 0):.0f} s")

    results = bc.run_pool(fit_video, tasks, args.workers, on_done=done)
    wall = time.perf_counter() - t0
    record = {"bench": "realistic", "quick": bool(args.quick), "spec": SPEC, "paper": PAPER,
              "settings": {"videos": videos, "scenes": scenes, "seed": args.seed, "train": train,
                           "workers": args.workers, "calibrate": calibrate, "scene_kwargs": QUICK_SCENE if args.quick else {}},
              "rows": aggregate(results), "videos": results, "wall_s": wall, "machine": bc.machine_info()}
    return bc.report_and_write(record, args.out, "realistic", print_report)


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
