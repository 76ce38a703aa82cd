"""`fitode batch MANIFEST`: fit every video a manifest lists, resumably, locally or on Ray.

Exit status: 0 when every job is complete, 1 when some failed or stopped early (the summary
says which and why), 2 for a bad manifest or flag, 130 when interrupted.
"""
from __future__ import annotations

import argparse
import sys

from fitode.errors import FitodeError
from fitode.names import parse_assignments, parse_names
from fitode.options import add_equation_arguments, add_training_arguments, positive_int, training_options


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("manifest", metavar="MANIFEST", help="a .csv or .toml file listing the videos (see the README)")
    p.add_argument("--out", metavar="DIR", help="the batch's folder (default MANIFEST-STEM-results beside the "
                   "manifest); re-running with the same folder resumes")
    ex = p.add_argument_group("where jobs run")
    ex.add_argument("--executor", choices=["local", "ray"], default="local",
                    help="local: a process pool on this machine (default); ray: a Ray cluster")
    ex.add_argument("--workers", type=positive_int, metavar="N",
                    help="jobs at once (default: the usable CPU cores; on Ray: the cluster's CPUs)")
    ex.add_argument("--address", metavar="ADDR", help="Ray cluster to join, e.g. ray://head:10001 or auto "
                    "(default: start a private local Ray instance)")
    rs = p.add_argument_group("resuming")
    rs.add_argument("--force", action="store_true", help="run every job again, even complete ones")
    rs.add_argument("--skip-failed", action="store_true",
                    help="keep jobs that failed before (same settings) as failed instead of retrying them")
    rs.add_argument("--dry-run", action="store_true", help="validate the manifest, say what would run, run nothing")

    # defaults for what the manifest leaves unset (a row wins over [defaults], which wins over these)
    add_equation_arguments(p, title="equation of every row that gives none", required=False, init=True)
    add_training_arguments(p, title="training, for what the manifest leaves unset", fields=TRAINING_FIELDS)
    d = p.add_argument_group("video, for what the manifest leaves unset")
    d.add_argument("--fps", type=float, metavar="F", help="real frame rate")
    d.add_argument("--stride", metavar="K|auto", help="frame stride (default auto)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or chatter; only errors")
    p.add_argument("--no-plots", action="store_true",
                   help="no job draws its pictures: result.json, fit.json and the tables only (seconds saved per clip)")


# each job runs single-threaded on its own core (and where the batch puts it): no --device, --threads
TRAINING_FIELDS = ("restarts", "max_steps", "min_steps", "window", "integrator", "encoder", "seed")


def defaults_from_args(args: argparse.Namespace) -> dict:
    """The flags as manifest keys (const.NAME, init.NAME, free), for rows that leave them unset."""
    out = {k: getattr(args, k) for k in ("eq", "eq_file", "system", "fps", "stride")
           if getattr(args, k, None) is not None}
    out.update(training_options(args, TRAINING_FIELDS))
    out.update({f"const.{k}": v for k, v in parse_assignments(args.const, "--const").items()})
    out.update({f"init.{k}": v for k, v in parse_assignments(args.init, "--init").items()})
    if args.free:
        out["free"] = parse_names(args.free, "--free")
    return out


def run(args: argparse.Namespace) -> int:
    from fitode.batch import format_aggregate, run_batch

    say = (lambda _line: None) if args.quiet else (lambda line: print(line, flush=True))
    if args.address and args.executor != "ray":
        raise FitodeError("--address is for --executor ray")
    result = run_batch(args.manifest, args.out, executor=args.executor, workers=args.workers,
                       address=args.address, force=args.force, retry_failed=not args.skip_failed,
                       defaults=defaults_from_args(args), progress=not args.quiet and sys.stderr.isatty(),
                       log=say, dry_run=args.dry_run, plots=not args.no_plots)
    if args.dry_run:
        return 0
    c = result.counts
    say(format_aggregate(result.aggregate))
    bad = [r for r in result.rows if r.status != "complete"]
    for r in bad[:10]:
        print(f"{r.status}: {r.name}: {r.error or 'not run'}", file=sys.stderr)
    if len(bad) > 10:
        print(f"... and {len(bad) - 10} more (see summary.csv)", file=sys.stderr)
    say(f"{c['complete']} complete, {c['failed']} failed, {c['incomplete']} incomplete "
        f"({len(result.ran)} run now, {len(result.reused)} reused) in {result.wall_s:.1f} s; "
        f"summary: {result.out_dir / 'summary.csv'}")
    return 0 if result.ok else 1
