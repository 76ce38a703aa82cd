"""speed_clip: a fit of a real clip against the time the same machine takes to decode it.

Issue 21's speed line: `fitode pendulum_bob_L062.mp4 --system pendulum` should finish in at most 3x
the time it takes to decode the clip. Side by side, each as a process of its own after a warm-up read:
the decode (Python, its imports and fitode.video.read_video with the command's defaults: stride
auto, short side 64, gray), then the whole command (`python -m fitode CLIP ARGS --quiet`: decode,
plan, fit, assessment, plots, result.json), each --reps times alternating, so a busy machine slows both alike; the load average is printed beside
them (the machine is shared: trust the ratio of minima more than either time).

    python bench/speed_clip.py                                  # the bob clip, --system pendulum
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

CLIP = Path(__file__).resolve().parents[1].parent / "shared" / "realvideos" / "pendulum_bob_L062.mp4"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=None)
    parser.add_argument("--clip", default=str(CLIP), help=f"the video (default {CLIP})")
    parser.add_argument("--args", default="--system pendulum", help="the command's flags (default: --system pendulum)")
    parser.add_argument("--reps", type=int, default=1, help="alternating repetitions (default 1)")


def _timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise FitodeError(f"{' '.join(cmd[:4])} ... failed: {(done.stderr or done.stdout).strip()[-300:]}")
    return time.perf_counter() - t0


def _decode(clip: str) -> float:
    """The decode as a process of its own (Python, imports and the read, as the command pays them)."""
    return _timed([sys.executable, "-c", f"from fitode.video import read_video; read_video({clip!r}, stride='auto')"])


def _fit(clip: str, argv: list[str], out: Path) -> tuple[float, dict]:
    wall = _timed([sys.executable, "-m", "fitode", clip, *argv, "--quiet", "--out", str(out)])
    res = json.loads((out / "result.json").read_text())
    return wall, {"values": {k: v["value"] for k, v in res.get("parameters", {}).items()},
                  "verdicts": {k: v.get("verdict") for k, v in res.get("parameters", {}).items()},
                  "observation": res.get("plan", {}).get("observation", {}).get("value")}


def run(args: argparse.Namespace) -> int:
    clip = str(args.clip)
    if not Path(clip).is_file():
        print(f"skip: {clip} not found")
        return 0
    argv = shlex.split(args.args)
    _decode(clip)  # warm-up: the codec and the imports in the file cache
    decode, fits, last = [], [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(max(1, args.reps)):
            decode.append(_decode(clip))
            wall, last = _fit(clip, argv, Path(tmp) / f"run{rep}")
            fits.append(wall)
    load = os.getloadavg()
    record = {"clip": clip, "args": argv, "decode_s": decode, "fit_s": fits, "ratio": min(fits) / min(decode),
              "load": list(load), "result": last, "machine": bc.machine_info()}
    return bc.report_and_write(record, args.out, "speed_clip", _print)


def _print(record) -> None:
    rows = [{"clip": Path(record["clip"]).name, "args": " ".join(record["args"]),
             "decode s": f"{min(record['decode_s']):.2f}", "command s": f"{min(record['fit_s']):.2f}",
             "ratio": f"{record['ratio']:.1f}x", "load (1/5/15 min)": " ".join(f"{x:.1f}" for x in record["load"])}]
    print(bc.format_table(rows, [(k, k) for k in rows[0]]))
    res = record["result"]
    print(f"observation {res.get('observation')}; "
          + ", ".join(f"{k} = {v:.5g} ({res['verdicts'].get(k)})" for k, v in res.get("values", {}).items()))


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
