"""Regenerate the README's quick start: run its command, put the transcript into README.md and
draw docs/quickstart.png from the run's folder.

    .venv/bin/python docs/quickstart.py

The command is the README's own, run in the repository's root (its folder goes under
./fitode-runs/, as for a user). tests/test_readme.py keeps the transcript's header (the lines
printed before training) equal to what the command prints today.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMAND = ["fitode", "fitode/examples/pendulum.mp4", "--eq-file", "fitode/examples/pendulum.toml"]
BEGIN = "<!-- quickstart transcript: written by docs/quickstart.py -->"
END = "<!-- end of the quickstart transcript -->"
PICTURE = ROOT / "docs" / "quickstart.png"
TRUTH = {"L": 0.25, "zeta": 0.15}


def transcript_block(readme: str) -> list[str]:
    """The transcript lines between the README's markers, unindented."""
    inside = readme.split(BEGIN, 1)[1].split(END, 1)[0]
    return [line[4:] for line in inside.strip("\n").split("\n") if line.startswith("    ")]


def header(lines: list[str]) -> list[str]:
    """The lines printed before training: every one of them is the same on every run and machine."""
    out = []
    for line in lines:
        if re.match(r"^run\s+\d", line):
            break
        out.append(line)
    return out


def main() -> int:
    exe = Path(sys.executable).parent / "fitode"
    t = time.time()
    p = subprocess.run([str(exe), *COMMAND[1:]], cwd=ROOT, capture_output=True, text=True)
    wall = time.time() - t
    if p.returncode != 0:
        print(p.stdout + p.stderr, file=sys.stderr)
        return 1
    lines = [line.rstrip() for line in p.stdout.splitlines() if line.strip()]
    folder = ROOT / lines[-1].split("results: ", 1)[1]
    readme_path = ROOT / "README.md"
    readme = readme_path.read_text()
    block = "\n".join("    " + line for line in lines)
    readme = readme.split(BEGIN, 1)[0] + BEGIN + "\n\n" + block + "\n\n" + END + readme.split(END, 1)[1]
    readme_path.write_text(readme)
    draw(folder)
    print(f"{' '.join(COMMAND)}: {wall:.0f} s; README.md transcript and {PICTURE.relative_to(ROOT)} rewritten")
    return 0


def draw(folder: Path) -> Path:
    """A small picture of the result: a frame of the clip, and the encoded latent (or the measured
    state) against the equation's trajectory with the estimates."""
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    import numpy as np

    from fitode.pipeline import read_clip

    report = json.loads((folder / "result.json").read_text())
    clip, _ = read_clip(ROOT / COMMAND[1])
    traj = report["trajectory"]
    t = np.asarray(traj["time"])
    z, r = np.asarray(traj["latent"])[:, 0], np.asarray(traj["rollout"])[:, 0]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8.0, 2.4), gridspec_kw={"width_ratios": [1, 3.6]})
    a.imshow(clip.frames[0, 0], cmap="gray")
    a.set_title("frame 0 (48x48)", fontsize=8)
    a.axis("off")
    observed = report["plan"]["observation"]["value"]
    encoded = observed == "any"  # the paper's free encoder, or a quantity measured in the frames
    b.plot(t, z, ".", ms=3, label="what the encoder read from each frame" if encoded else f"the {observed} measured in each frame")
    b.plot(t, r, "-", lw=1.2, label="the equation with the estimates")
    b.set_xlabel("time (s)", fontsize=8)
    b.set_ylabel("theta (latent units)" if encoded else "theta (rad)" if observed == "angle" else "theta", fontsize=8)
    b.tick_params(labelsize=7)
    lo, hi = float(min(z.min(), r.min())), float(max(z.max(), r.max()))
    b.set_ylim(lo - 0.05 * (hi - lo), hi + 0.45 * (hi - lo))  # room for the legend above the swing
    b.legend(fontsize=7, loc="upper center", ncol=2, frameon=False)
    est = report["parameters"]
    b.set_title("   ".join(f"{k} = {v['value']:.4g} {v['unit'] or ''} (truth {TRUTH[k]:g}), {v['verdict']}"
                           for k, v in est.items()), fontsize=8)
    fig.tight_layout()
    fig.savefig(PICTURE, dpi=80)
    plt.close(fig)
    return PICTURE


if __name__ == "__main__":
    sys.exit(main())
