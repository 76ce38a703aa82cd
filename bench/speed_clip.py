"""speed_clip: where the time of `fitode CLIP` goes, against the time the same machine takes to decode the clip.

Issue 33's speed lines: the bob clip (`fitode pendulum_bob_L062.mp4 --system pendulum`) within 2x
its decode, and a 60-frame 240 fps clip's whole process under 4 s. For each clip, side by side, each
as a process of its own after a warm-up read: the decode (Python, its imports and
fitode.video.read_video with the command's defaults: stride auto, short side 64, gray, and no
tracking: following the object is measuring, not reading), then the whole command (`python -m
fitode CLIP ARGS --quiet`), its stages timed inside the process:

- start-up: from the process's launch to the command's first stage (Python, the imports the
  command makes before it, the flags); the stages' functions are timed as their modules are
  imported by the command itself, so no import is moved into the start-up;
- read and measure: decoding the clip and resolving the plan (the observation read from the frames,
  a finer re-read), with the imports they pull in (torch, where the frames become a tensor; OpenCV);
- fit: the restarts (a measured path's direct fit, or the encoder's training) and the measurement's checks;
- intervals: the bootstrap of every constant's interval;
- assessment: the calibration where asked and the verdicts;
- pictures: the plots (track.png, frames.png, latent.png; params.png and loss.png where an encoder
  was trained);
- the rest: what none of these holds (printing, result.json, the tables);

and beside them, of which tracking: the object's track from the frames (the change detector and
the object tracker, fitode.video.track.TrackRecorder.finish), which the read runs; of which
imports: the seconds the process spent importing (Python's -X importtime, each import counted
once, where it happened), and the libraries that cost most of them. What the stages hold of these
is theirs too (the pictures' matplotlib, the reading's torch).

Each pair runs --reps times alternating, so a busy machine slows both alike; the load average is
printed beside them (the machine is shared: trust the ratio of minima more than either time).
The short clip is generated here (`fitode synth scene throw --fps 240`, 60 frames, 320x240, a
seeded throw) into a temporary folder; the project ships no camera clip.

    python bench/speed_clip.py                                  # the bob clip and a 240 fps throw
    python bench/speed_clip.py --clip X.mp4 --args "--system pendulum --observe position"

Prints one table; writes <out>/speed_clip.json.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402

from fitode.errors import FitodeError  # noqa: E402

# the shared real clips beside the checkout (a worktree sits one folder deeper than the main one)
CLIP = next((p / "shared" / "realvideos" / "pendulum_bob_L062.mp4" for p in Path(__file__).resolve().parents
             if (p / "shared" / "realvideos").is_dir()), Path("pendulum_bob_L062.mp4"))
SHORT = "throw 240 fps"  # the generated clip's name in --clip
# the stages, each the functions whose calls it sums (module, attribute); the first match of a name is patched
STAGES = {
    # measure_clip holds the read, the frames made a tensor (torch's import) and the plan
    "read and measure": [("fitode.pipeline", "measure_clip"), ("fitode.pipeline", "_read"), ("fitode.api", "plan"),
                         ("fitode.api", "measure")],
    "fit": [("fitode.train.trainer", "fit_frames")],
    "intervals": [("fitode.api", "_intervals")],
    "assessment": [("fitode.api", "_calibrate"), ("fitode.train.assess", "assess")],
    # the result's own pictures (latent, params, loss) are drawn by fitode.output's _try_plot, track
    # and frames by the name fitode.pipeline imported: both are patched, or three fall into the rest
    "pictures": [("fitode.pipeline", "_try_plot"), ("fitode.output", "_try_plot")],
}
COLUMNS = ["start-up", *STAGES, "the rest"]
# parts of a stage shown beside it, timed wherever they are called (the tracking runs inside the read)
PARTS = {"of which tracking": [("fitode.video.track", "TrackRecorder.finish")]}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=None)
    parser.add_argument("--clip", action="append",
                        help=f"a video (repeatable; default: {CLIP.name} and a generated 60-frame {SHORT} clip)")
    parser.add_argument("--args", action="append",
                        help="the command's flags, one per --clip (default: --system pendulum; the short clip's: "
                             "--system throw)")
    parser.add_argument("--reps", type=int, default=1, help="alternating repetitions (default 1)")


def _run(cmd: list[str], env: dict | None = None, log: bool = False):
    """The command's wall seconds (and its standard error, with log)."""
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        tail = "\n".join(line for line in (done.stderr or done.stdout).splitlines() if not line.startswith("import time:"))
        raise FitodeError(f"{' '.join(cmd[:4])} ... failed: {tail.strip()[-300:]}")
    wall = time.perf_counter() - t0
    return (wall, done.stderr) if log else wall


def imports(log: str, top: int = 3) -> dict:
    """What -X importtime's lines in log say: the seconds spent importing in all (each outermost
    import's cumulative time: a module imported inside a function at run time is one too), and the
    `top` top-level packages that cost most, {name: seconds}, each the time its own modules took
    to run (their self time: torch's, not what fitode's modules spent importing torch)."""
    total, per = 0.0, {}
    for line in log.splitlines():
        if not line.startswith("import time:"):
            continue
        parts = line.split("|")
        own, whole = (parts[0].split(":")[-1].strip(), parts[1].strip()) if len(parts) == 3 else ("", "")
        if not (own.isdigit() and whole.isdigit()):
            continue  # the header
        name = parts[2].rstrip()
        if not name.startswith("  "):  # an outermost import: what it holds is counted with it
            total += int(whole) / 1e6
        root = name.strip().split(".")[0]
        per[root] = per.get(root, 0.0) + int(own) / 1e6
    biggest = dict(sorted(per.items(), key=lambda kv: -kv[1])[:top])
    return {"total": total, "biggest": biggest}


def _decode(clip: str) -> float:
    """The decode as a process of its own: Python, its imports and the frames read as the command
    reads them (stride, crop, downscale), without the object's tracking, which is the command's
    measuring (its own column), not reading the clip."""
    return _run([sys.executable, "-c",
                 f"from fitode.video import read_video; read_video({clip!r}, stride='auto', track=False)"])


def _fit(clip: str, argv: list[str], out: Path) -> tuple[float, dict, dict]:
    """The whole command in a process of its own, its stages timed inside it (_driver)."""
    stages = out.with_suffix(".stages.json")
    env = {**os.environ, "SPEED_CLIP_STAGES": str(stages), "SPEED_CLIP_LAUNCH": repr(time.time())}
    wall, log = _run([sys.executable, "-X", "importtime", __file__, "--driver", clip, *argv, "--quiet", "--out",
                      str(out)], env, log=True)
    times = json.loads(stages.read_text())
    times["imports"] = imports(log)
    res = json.loads((out / "result.json").read_text())
    return wall, times, {"values": {k: v["value"] for k, v in res.get("parameters", {}).items()},
                         "verdicts": {k: v.get("verdict") for k, v in res.get("parameters", {}).items()},
                         "observation": res.get("plan", {}).get("observation", {}).get("value")}


def _driver(argv: list[str]) -> int:
    """`fitode ARGV` in this process with each stage's functions timed; writes the times
    (seconds, and start-up from the launch time the parent passed) to $SPEED_CLIP_STAGES."""
    entered = time.time()
    spent = {name: 0.0 for name in [*STAGES, *PARTS]}
    depth, first = [0], []

    def timed(stage, fn):
        def wrapper(*args, **kw):
            if depth[0]:  # a stage inside another (a plot inside the pictures) counts once
                return fn(*args, **kw)
            first.append(first[0] if first else time.time())
            depth[0] += 1
            t0 = time.perf_counter()
            try:
                return fn(*args, **kw)
            finally:
                spent[stage] += time.perf_counter() - t0
                depth[0] -= 1
        return wrapper

    def part(name, fn):
        def wrapper(*args, **kw):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kw)
            finally:
                spent[name] += time.perf_counter() - t0
        return wrapper
    # each stage's functions patched as the command imports their module, not before: importing
    # them here would put what they import (torch, the plots) into the start-up
    targets: dict[str, list] = {}
    for stage, where in [*STAGES.items(), *PARTS.items()]:
        for module, name in where:
            targets.setdefault(module, []).append((stage, name))
    hook = _PatchOnImport(targets, lambda stage, fn: (part if stage in PARTS else timed)(stage, fn))
    for module in [m for m in targets if m in sys.modules]:  # imported with the driver's own
        hook.patch(sys.modules[module])
    sys.meta_path.insert(0, hook)
    from fitode.cli import entry
    try:
        code = entry(argv)  # the command's own entry: its collector's settings are part of its time
    finally:
        done = time.time()
        launch = float(os.environ.get("SPEED_CLIP_LAUNCH", entered))
        # start-up: the launch to the first stage (Python, the imports, the flags)
        Path(os.environ["SPEED_CLIP_STAGES"]).write_text(json.dumps(
            {"start-up": (first[0] if first else done) - launch, **spent, "whole_in_process": done - entered}))
    return int(code or 0)


class _PatchOnImport:
    """A finder that lets the others find a module and, once the module has run, wraps the named
    functions of it ({module: [(stage, name)]}) with timed(stage, fn)."""

    def __init__(self, targets: dict, timed):
        self.targets, self.timed = targets, timed

    def find_spec(self, name, path=None, target=None):
        if name not in self.targets:
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is not None:
                break
        else:
            return None
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            self.patch(module)
        spec.loader.exec_module = exec_module
        return spec

    def patch(self, module) -> None:
        for stage, attr in self.targets[module.__name__]:
            *owner_path, name = attr.split(".")  # "Class.method": the method on its class
            owner = module
            for step in owner_path:
                owner = getattr(owner, step, None)
            if owner is not None and hasattr(owner, name):
                setattr(owner, name, self.timed(stage, getattr(owner, name)))


def _short_clip(folder: Path) -> Path:
    path = folder / "throw240.mp4"
    _run([sys.executable, "-m", "fitode", "synth", "scene", "throw", "--fps", "240", "--duration", "0.25",
          "--size", "320x240", "--seed", "3", "--out", str(path)])
    return path


def run(args: argparse.Namespace) -> int:
    if args.clip:
        flags = (args.args or []) + ["--system pendulum"] * (len(args.clip) - len(args.args or []))
        pairs = list(zip(args.clip, flags))
    else:  # the bob clip (with --args where given) and the short clip
        pairs = [(str(CLIP), (args.args or ["--system pendulum"])[0]), (SHORT, "--system throw")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for clip, argv in pairs:
            name = clip
            if clip == SHORT:
                clip = str(_short_clip(Path(tmp)))
            elif not Path(clip).is_file():
                print(f"skip: {clip} not found")
                continue
            argv = shlex.split(argv)
            _decode(clip)  # warm-up: the codec and the imports in the file cache
            decode, fits, stages, last = [], [], [], {}
            for rep in range(max(1, args.reps)):
                decode.append(_decode(clip))
                wall, times, last = _fit(clip, argv, Path(tmp) / f"{len(rows)}-run{rep}")
                fits.append(wall)
                stages.append(times)
            best = min(range(len(fits)), key=fits.__getitem__)
            times = stages[best]
            times["the rest"] = max(0.0, fits[best] - times["start-up"] - sum(times[s] for s in STAGES))
            rows.append({"clip": Path(name).name, "args": argv, "decode_s": decode, "fit_s": fits,
                         "stages_s": {**{c: times[c] for c in [*COLUMNS, *PARTS]}, "imports": times["imports"]},
                         "ratio": min(fits) / min(decode),
                         "load": list(os.getloadavg()), "result": last})
    record = {"clips": rows, "machine": bc.machine_info()}
    return bc.report_and_write(record, args.out, "speed_clip", _print)


def _print(record) -> None:
    rows = []
    for r in record["clips"]:
        row = {"clip": r["clip"], "decode s": f"{min(r['decode_s']):.2f}", "command s": f"{min(r['fit_s']):.2f}",
               "ratio": f"{r['ratio']:.1f}x"}
        row.update({c: f"{r['stages_s'][c]:.2f}" for c in [*COLUMNS, *PARTS]})
        held = r["stages_s"].get("imports") or {}
        row["of which imports"] = (f"{held['total']:.2f} (" + ", ".join(f"{k} {v:.2f}" for k, v in held["biggest"].items())
                                   + ")") if held else "-"
        row["load (1/5/15 min)"] = " ".join(f"{x:.1f}" for x in r["load"])
        rows.append(row)
    if not rows:
        return
    print(bc.format_table(rows, [(k, k) for k in rows[0]]))
    for r in record["clips"]:
        res = r["result"]
        print(f"{r['clip']} ({' '.join(r['args'])}): observation {res.get('observation')}; "
              + ", ".join(f"{k} = {v:.5g} ({res['verdicts'].get(k)})" for k, v in res.get("values", {}).items()))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--driver":
        sys.exit(_driver(sys.argv[2:]))
    sys.exit(bc.script_main(__doc__, add_arguments, run))
