"""`fitode synth`: render a synthetic video with known constants, and its ground truth.

    fitode synth paper motion --out motion.mp4
    fitode synth equation --eq "x'' = -k*x - c*x'" --const k=4 c=0.1 --y0 x=1 "x'=0" \\
        --mode scale --out osc.npy
    fitode synth scene pendulum --setting 0.9 --seed 2 --out pend.mp4

Each writes the video (.mp4 or .npy) and <stem>.truth.json beside it.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

from fitode.errors import FitodeError
from fitode.names import parse_assignments
from fitode.options import add_equation_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from fitode.synth import MODES, PAPER_KINDS, SCENES

    sub = parser.add_subparsers(dest="what", metavar="{paper,equation,scene}", required=True)

    paper = sub.add_parser("paper", help="the paper's synthetic datasets: z'' + g1 z' + g0 z = 0",
                           description="One of the paper's three synthetic videos (50x50, exact closed form).")
    paper.add_argument("kind", choices=PAPER_KINDS, help="motion (pendulum angle), intensity (gray "
                       "level of a shape) or scale (radius of a circle)")
    paper.add_argument("--g0", type=float, default=4.0016, help="default 4.0016 (omega = 2, zeta = 0.04)")
    paper.add_argument("--g1", type=float, default=0.08, help="default 0.08")
    paper.add_argument("--z0", type=float, default=1.0, help="z(0), default 1")
    paper.add_argument("--v0", type=float, default=None, help="z'(0), default -g1/2 * z0 (the paper's)")
    _clean_options(paper)
    _common(paper)

    eq = sub.add_parser("equation", help="any equation, simulated (RK4) and rendered",
                        description="Simulate an equation with fitode's RK4 and render each state "
                                    "as motion, intensity or scale.")
    # no --eq-file or --free: the renderer takes a shipped name or text and needs every constant's value
    add_equation_arguments(eq, eq_file=False, free=False, many=True,
                           const_help="value of every learnable constant (and optionally known ones such as g)")
    eq.add_argument("--y0", metavar="NAME=VALUE", nargs="+", action="extend", default=[],
                    help="initial state: every state, optionally derivatives (quote primes: \"x'=0\"; "
                         "missing derivatives are 0)")
    eq.add_argument("--mode", choices=MODES, default="motion", help="how a state is drawn (default motion)")
    eq.add_argument("--substeps", type=int, default=20, help="RK4 steps per frame (default 20)")
    _clean_options(eq)
    _common(eq)

    sc = sub.add_parser("scene", help="a realistic scene (60 fps, textured, noisy, compressed)",
                        description="A realistic scene modelled on the paper's real dataset.")
    sc.add_argument("name", choices=tuple(SCENES), help="; ".join(
        f"{n}: {i.setting} in {', '.join(f'{s:g}' for s in i.settings)} {i.unit}" for n, i in SCENES.items()))
    sc.add_argument("--setting", type=float, default=None, help="the scene's varied quantity "
                    "(default: the dataset's middle value)")
    sc.add_argument("--param", metavar="NAME=VALUE", nargs="+", action="extend", default=[],
                    help="scene parameters (" + "; ".join(
                        f"{n}: {' '.join(i.params)}" for n, i in SCENES.items() if i.params) + ")")
    sc.add_argument("--duration", type=float, default=None, help="seconds (default: the scene's)")
    sc.add_argument("--fps", type=float, default=60.0, help="frames per second (default 60)")
    sc.add_argument("--store-fps", type=float, default=None, metavar="F",
                    help="the frame rate the file says (a phone stores its 240 fps slow motion at 30; "
                         "default: --fps); fit it with --fps at the filmed rate")
    from fitode.video import parse_size
    sc.add_argument("--size", type=parse_size, default="480x270", metavar="WxH",
                    help="frame size, width x height in pixels (default 480x270)")
    sc.add_argument("--noise", type=float, default=1.0, help="sensor noise multiplier (default 1, 0: none)")
    sc.add_argument("--jpeg-quality", type=int, default=85, help="per-frame JPEG quality (default 85, 100: none)")
    _common(sc)


def _clean_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=int, default=270, help="number of frames (default 270)")
    p.add_argument("--dt", type=float, default=0.2, help="seconds between frames (default 0.2)")
    p.add_argument("--size", type=int, default=50, help="side of the square frames in pixels (default 50)")
    p.add_argument("--noise", type=float, default=0.0, help="std of Gaussian pixel noise (default 0)")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, metavar="PATH", help="output video, .mp4 or .npy")
    p.add_argument("--format", choices=("mp4", "npy"), default=None,
                   help="video format (default: from the --out suffix)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--force", action="store_true", help="overwrite existing files")


def run(args: argparse.Namespace) -> int:
    from fitode import synth

    out = _out_path(args.out, args.format)
    truth = synth.truth_path(out)
    if not args.force:
        for p in (out, truth):
            if p.exists():
                raise FitodeError(f"{p} exists; pass --force to overwrite it")
    if args.what == "paper":
        v = synth.paper_video(args.kind, n_frames=args.frames, dt=args.dt, size=args.size, seed=args.seed,
                              g0=args.g0, g1=args.g1, z0=args.z0, v0=args.v0, noise=args.noise)
    elif args.what == "equation":
        v = synth.render_equation(args.system or args.eq, constants=parse_assignments(args.const, "--const"),
                                  y0=_pairs(args.y0, "--y0"), n_frames=args.frames, dt=args.dt,
                                  mode=args.mode, size=args.size, seed=args.seed, substeps=args.substeps,
                                  noise=args.noise)
    else:
        v = synth.scene(args.name, args.setting, seed=args.seed, duration=args.duration, fps=args.fps,
                        size=args.size, noise=args.noise, jpeg_quality=args.jpeg_quality,
                        **_pairs(args.param, "--param"))
        if args.store_fps is not None:
            if not (args.store_fps > 0 and math.isfinite(args.store_fps)):
                raise FitodeError(f"--store-fps must be a positive number, got {args.store_fps:g}")
            v = dataclasses.replace(v, dt=1.0 / args.store_fps)
    synth.write_video(v, out)
    consts = ", ".join(f"{k} = {val:.6g}" for k, val in v.truth.items())
    print(f"wrote {out} ({v.n_frames} frames, {v.size[1]}x{v.size[0]}, dt = {v.dt:.6g} s) "
          f"and {truth.name}")
    print(f"equation: {v.equation}; truth: {consts}")
    return 0


def _out_path(text: str, fmt: str | None) -> Path:
    out = Path(text)
    suffix = out.suffix.lower()
    if suffix in (".mp4", ".npy"):
        if fmt is not None and suffix[1:] != fmt:
            raise FitodeError(f"--out {text} is .{suffix[1:]} but --format says {fmt}")
        return out
    if suffix and fmt is None:
        raise FitodeError(f"cannot write '{suffix}' videos: name the output .mp4 or .npy (or give --format)")
    return out.with_name(out.name + "." + (fmt or "mp4"))


def _pairs(items: list[str], flag: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise FitodeError(f"{flag} wants NAME=VALUE, got '{item}'")
        try:
            out[name] = float(value)
        except ValueError:
            raise FitodeError(f"{flag} {name}: '{value}' is not a number") from None
    return out
