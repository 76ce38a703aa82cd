"""Frame times: a generated oscillator stored clean, by 24 -> 30 pulldown and as a phone stamps it.

A dot swinging as z'' = -k*z - c*z' (k = 16, c = 0.3, the paper's pendulum drawing), rendered at
600 fps and sampled at each clip's times (fitode.synth.timing): clean at 30 and at 24 fps, the
24 fps clip converted to 30 by repeating every fourth frame, and a phone's clip (8% jitter, 4
dropped frames). Each is fitted with `fitode CLIP --eq "z'' = -k*z - c*z'"` (default flags);
the table sets the pulldown clip against the clean 24 fps one and the phone's against the
clean 30 fps one (issue #22: within 1%).

    python bench/timing.py              # 4 fits, minutes each on 2 cores
    python bench/timing.py --quick      # a smoke test: 40 steps, numbers mean nothing
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as bc  # noqa: E402

EQ = "z'' = -k*z - c*z'"
TRUTH = {"k": 16.0, "c": 0.3}
AGAINST = {"pulldown": "clean24", "phone": "clean30"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    bc.add_common_arguments(parser, workers=None)


def make_clips(folder: Path) -> dict[str, Path]:
    from fitode.synth import render_equation
    from fitode.synth.timing import phone_times, pulldown, sample_at, write_timed

    fine = render_equation(EQ, constants=TRUTH, y0={"z": 1.0}, n_frames=6001, dt=1 / 600, mode="motion", size=48)
    t30, t24 = np.arange(300) / 30, np.arange(240) / 24
    tv = phone_times(296, 30.0, jitter=0.08, drops=4, seed=1)
    return {"clean30": write_timed(sample_at(fine, t30), t30, folder / "clean30.mp4", 30),
            "clean24": write_timed(sample_at(fine, t24), t24, folder / "clean24.mp4", 24),
            "pulldown": write_timed(pulldown(sample_at(fine, t24)), t30, folder / "pulldown.mp4", 30),
            "phone": write_timed(sample_at(fine, tv), tv, folder / "phone.mp4", 30)}


def run(args: argparse.Namespace) -> int:
    import fitode
    from fitode.video import read_video

    options = {"max_steps": 40, "min_steps": 0} if args.quick else {}
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory(prefix="fitode-bench-timing-") as tmp:
        for name, path in make_clips(Path(tmp)).items():
            bc.progress(f"timing: {name} ...")
            clip = read_video(path)
            result = fitode.fit(str(path), eq=EQ, progress=False, **options)
            rows.append({"clip": name, "fps": f"{clip.fps:.6g}", "timing": "; ".join(clip.timing) or "-",
                         **{n: result.parameters[n].value for n in TRUTH},
                         **{f"{n}_verdict": result.verdicts[n]["verdict"] for n in TRUTH}})
    by = {r["clip"]: r for r in rows}
    for r in rows:
        ref = by.get(AGAINST.get(r["clip"], ""))
        for n in TRUTH:
            r[f"{n}_vs"] = f"{100 * (r[n] / ref[n] - 1):+.2f}%" if ref else ""
    shown = [{**r, **{n: f"{r[n]:.5g}" for n in TRUTH}} for r in rows]
    columns = [("clip", "clip"), ("fps", "fps"), ("k", "k"), ("vs clean", "k_vs"), ("c", "c"), ("vs clean", "c_vs"),
               ("verdicts", "k_verdict")]
    print(bc.format_table(shown, columns, title=f"{EQ}, k = 16, c = 0.3: each clip against its clean version"))
    for r in rows:
        print(f"{r['clip']}: {r['timing']}")
    record = {"bench": "timing", "quick": bool(args.quick), "rows": rows, "wall_s": time.perf_counter() - t0,
              "machine": bc.machine_info()}
    print(f"wrote {bc.write_record(record, args.out, 'timing')}")
    return 0


if __name__ == "__main__":
    sys.exit(bc.script_main(__doc__, add_arguments, run))
