"""`fitode VIDEO (--eq TEXT | --eq-file PATH | --system NAME) [options]`: fit one video.

--eq repeated (or an equation file with `alternatives`) compares the candidate equations
(fitode.compare) and reports the preferred one, with a table of every candidate.

Prints what it understood, trains, prints a table of the estimates, and writes an output folder
(result.json, fit.json, estimates.csv, track.csv, latent.png, frames.png, track.png, and where an
encoder was trained params.png and loss.png). --json prints result.json on stdout and moves every human line to stderr, so stdout
is pure JSON.
"""
from __future__ import annotations

import argparse
import json
import sys

from fitode.options import (add_equation_arguments, add_training_arguments, fraction, prior_value,
                            training_options)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("video", metavar="VIDEO",
                   help="video file (mp4, avi, mov, ...), folder of images (needs --fps) or .npy array of frames")
    eq, _ = add_equation_arguments(p, init=True, candidates=True)
    eq.add_argument("--prior", metavar="MEAN,STD", type=prior_value,
                    help="prior on the latent, N(MEAN, STD^2) (default 0,1 or the equation file's)")
    eq.add_argument("--calibrate", metavar="TEXT",
                    help="known values of a state, \"h(0)=0.07; h(25)=0.01\" (seconds of the video), "
                         "to report scale-dependent constants in physical units")
    eq.add_argument("--scale", metavar="X1,Y1,X2,Y2=D",
                    help="two points of the source frame (pixels; x right, y down, as --roi) that lie D metres "
                         "apart in the plane of the motion (D±U with its uncertainty; each end ±1 pixel): "
                         "positions in metres, y up, and constants in SI units (default: source pixels)")

    tr = add_training_arguments(p)
    from fitode.train.observe.catalog import help_text
    tr.add_argument("--observe", type=observe_value, default=None, metavar="MODEL", help=help_text())
    tr.add_argument("--train-fraction", type=fraction, metavar="F", default=None,
                    help="train on the first fraction of the frames; the rest shows extrapolation (default 1)")

    from fitode.video import add_video_arguments
    add_video_arguments(p)  # parsed on the spot: args.roi, args.size, args.stride are read_video's values

    out = p.add_argument_group("output")
    out.add_argument("--out", metavar="DIR", help="output folder (default a new one under ./fitode-runs/); "
                     "must not exist or be empty")
    out.add_argument("--quiet", action="store_true", help="no progress or chatter; the table is still printed")
    out.add_argument("--json", action="store_true", help="print result.json on stdout (human text goes to stderr)")
    out.add_argument("--no-plots", action="store_true",
                     help="no pictures: result.json, fit.json and the tables only (seconds saved per clip)")


def observe_value(text: str) -> str | dict[str, str]:
    """--observe's value: a model's name, or one per state ("x=position;y=size")."""
    from fitode.errors import ConfigError
    from fitode.train.observe.catalog import parse_observe
    try:
        return parse_observe(text)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    from fitode.names import parse_assignments
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
        say(f"results (interrupted during the {stop.outcome.report.get('stage', 'training')}): "
            f"{stop.outcome.out_dir}")
        raise
    say(format_table(outcome.report))
    if not args.quiet:
        say(f"results: {outcome.out_dir}")
    if args.json:
        sys.stdout.write(json.dumps(outcome.report, indent=1) + "\n")
        sys.stdout.flush()
    return 0


def _run(args, const, init, say):
    from fitode.pipeline import ReadOptions, run_video
    from fitode.video import video_kwargs
    fit = dict(eq=args.eq, eq_file=args.eq_file, system=args.system, const=const, free=tuple(args.free),
               init=init or None, prior=args.prior, calibrate=args.calibrate, scale=args.scale, observe=args.observe,
               **training_options(args))
    if args.train_fraction is not None:
        fit["train_fraction"] = args.train_fraction
    return run_video(args.video, args.out, read=ReadOptions(**video_kwargs(args)), fit=fit,
                     progress=not args.quiet and sys.stderr.isatty(), log=None if args.quiet else say,
                     plots=not args.no_plots)
