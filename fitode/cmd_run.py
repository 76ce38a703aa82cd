"""`fitode VIDEO (--eq TEXT | --eq-file PATH | --system NAME) [options]`: fit one video.

Prints what it understood, trains, prints a table of the estimates, and writes an output folder
(result.json, fit.json, latent.png, params.png, loss.png, frames.png). --json prints result.json
on stdout and moves every human line to stderr, so stdout is pure JSON.
"""
from __future__ import annotations

import argparse
import json
import sys

from fitode.errors import FitodeError
from fitode.options import positive_int


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("video", metavar="VIDEO",
                   help="video file (mp4, avi, mov, ...), folder of images (needs --fps) or .npy array of frames")
    eq = p.add_argument_group("equation (exactly one)")
    ex = eq.add_mutually_exclusive_group(required=True)
    ex.add_argument("--eq", metavar="TEXT", help="the equation, e.g. \"x'' = -g/L*sin(x) - z*x'\"")
    ex.add_argument("--eq-file", metavar="PATH", help="an equation file (TOML)")
    ex.add_argument("--system", metavar="NAME", help=f"a shipped equation file by name: {_systems()}")
    eq.add_argument("--const", metavar="NAME=VALUE", action="append", default=[],
                    help="fix a constant to a value (repeatable)")
    eq.add_argument("--free", metavar="NAME", action="append", default=[],
                    help="learn a known constant such as g instead of fixing it (repeatable)")
    eq.add_argument("--init", metavar="NAME=VALUE", action="append", default=[],
                    help="start every restart from this value of a constant (repeatable)")
    eq.add_argument("--prior", metavar="MEAN,STD", help="prior on the latent, N(MEAN, STD^2) (default 0,1 "
                    "or the equation file's)")
    eq.add_argument("--calibrate", metavar="TEXT",
                    help="known values of a state, \"h(0)=0.07; h(25)=0.01\" (seconds of the video), "
                         "to report scale-dependent constants in physical units")

    tr = p.add_argument_group("training")
    tr.add_argument("--restarts", type=positive_int, metavar="N", help="independent restarts (default 3)")
    tr.add_argument("--max-steps", type=positive_int, metavar="N", help="step limit per restart (default 2000)")
    tr.add_argument("--window", type=positive_int, metavar="N", help="frames per training window (default 20)")
    tr.add_argument("--integrator", choices=["rk4", "euler", "symplectic"], help="ODE integrator (default rk4)")
    tr.add_argument("--encoder", choices=["mlp", "cnn", "linear"], help="frame encoder: mlp (default, the paper's), cnn, or linear (an affine map of the pixels: for decays, see README)")
    tr.add_argument("--device", choices=["cpu", "cuda"], help="where to train (default cpu)")
    tr.add_argument("--seed", type=int, metavar="N", help="random seed (default 0)")
    tr.add_argument("--workers", type=positive_int, metavar="N",
                    help="run the restarts in N single-threaded processes at once (default: one per restart, "
                         "up to the number of cores; 1 runs them one after another with a step-by-step bar)")
    tr.add_argument("--train-fraction", type=float, metavar="F", default=None,
                    help="train on the first fraction of the frames; the rest shows extrapolation (default 1)")

    from fitode.video import add_video_arguments
    add_video_arguments(p)  # parsed on the spot: args.roi, args.size, args.stride are read_video's values

    out = p.add_argument_group("output")
    out.add_argument("--out", metavar="DIR", help="output folder (default a new one under ./fitode-runs/); "
                     "must not exist or be empty")
    out.add_argument("--quiet", action="store_true", help="no progress or chatter; the table is still printed")
    out.add_argument("--json", action="store_true", help="print result.json on stdout (human text goes to stderr)")


def _systems() -> str:
    try:
        from fitode.eqfile import list_systems
        return ", ".join(list_systems())
    except Exception:  # noqa: BLE001 - help text must never break the command
        return "see fitode/equations/"


def parse_prior(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    parts = [s.strip() for s in text.split(",")]
    try:
        if len(parts) != 2:
            raise ValueError
        mean, std = float(parts[0]), float(parts[1])
    except ValueError:
        raise FitodeError(f"--prior expects MEAN,STD such as 1,0.2; got {text!r}") from None
    if not (std > 0) or not all(map(_finite, (mean, std))):
        raise FitodeError(f"--prior {text}: STD must be a positive number and both must be finite")
    return mean, std


def _finite(v: float) -> bool:
    return v == v and abs(v) != float("inf")


def train_options(args: argparse.Namespace) -> dict:
    opts = {}
    for flag, key in (("restarts", "restarts"), ("max_steps", "max_steps"), ("window", "window"),
                      ("integrator", "integrator"), ("encoder", "encoder"), ("device", "device"), ("seed", "seed"),
                      ("workers", "workers")):
        v = getattr(args, flag)
        if v is not None:
            opts[key] = v
    if "workers" not in opts and opts.get("device", "cpu") == "cpu":
        # small models: one single-threaded process per restart beats intra-op threads, and by far
        # when the machine is busy (measured on the bundled example: 53 s against 537 s under load)
        import os
        opts["workers"] = max(1, min(opts.get("restarts", 3), os.cpu_count() or 1))
    return opts


def run(args: argparse.Namespace) -> int:
    from fitode.options import parse_assignments
    from fitode.pipeline import RunInterrupted
    from fitode.report import format_table

    human = sys.stderr if args.json else sys.stdout

    def say(line: str) -> None:
        print(line, file=human, flush=True)

    const = parse_assignments(args.const)
    init = parse_assignments(args.init)
    try:
        outcome = _run(args, const, init, say)
    except RunInterrupted as stop:  # the folder is written; show what the restarts had reached
        say(format_table(stop.outcome.report))
        say(f"results (incomplete): {stop.outcome.out_dir}")
        raise
    say(format_table(outcome.report))
    if not args.quiet:
        say(f"results: {outcome.out_dir}")
    if args.json:
        sys.stdout.write(json.dumps(outcome.report, indent=1) + "\n")
        sys.stdout.flush()
    return 0


def _run(args, const, init, say):
    from fitode.pipeline import DEFAULT_TRAIN_FRACTION, run_video
    return run_video(
        args.video, args.out, eq=args.eq, eq_file=args.eq_file, system=args.system, const=const,
        free=tuple(args.free), init=init or None, prior=parse_prior(args.prior), fps=args.fps, start=args.start,
        end=args.end, roi=args.roi, size=args.size, color=args.color, stride=args.stride, mask=args.mask,
        calibrate=args.calibrate,
        train_fraction=args.train_fraction if args.train_fraction is not None else DEFAULT_TRAIN_FRACTION,
        progress=not args.quiet and sys.stderr.isatty(), log=None if args.quiet else say, **train_options(args))
