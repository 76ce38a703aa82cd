"""Peak memory and time of read_video on a long full-HD video.

Generates a 1920x1080, 60 fps, 60 s video (mp4v, a swinging disc over a textured background;
it is big, so it goes to /tmp, never into the repository), then reads it with `read_video`
under several settings, each in a fresh subprocess so that neither the generator nor an
earlier reading counts. Peak RSS is the child's `resource.getrusage(RUSAGE_SELF).ru_maxrss`;
"baseline" is a child that only imports fitode.video (Python + numpy + OpenCV).

    python bench/video_memory.py                 # the full 60 s run (about 5 minutes)
    python bench/video_memory.py --seconds 5     # a quick look

Prints a table and writes bench/out/video_memory.json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from fitode.jsonio import write_json

HERE = Path(__file__).resolve().parent

CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from fitode.video import read_video
kwargs = json.loads(sys.argv[2])
if sys.argv[1] == "-":
    out = {"frames": 0, "shape": None, "stride": None}
else:
    if "roi" in kwargs: kwargs["roi"] = tuple(kwargs["roi"])
    clip = read_video(sys.argv[1], **kwargs)
    out = {"frames": len(clip.frames), "shape": list(clip.frames.shape), "stride": clip.stride,
           "frames_mb": clip.frames.nbytes / 2**20, "reason": clip.stride_reason}
out["wall_s"] = time.perf_counter() - t0
use = resource.getrusage(resource.RUSAGE_SELF)
out["cpu_s"] = use.ru_utime + use.ru_stime  # less sensitive than wall time to a busy machine
out["maxrss_mb"] = use.ru_maxrss / 1024  # KiB on Linux
print(json.dumps(out))
"""

SETTINGS = [
    ("baseline (imports only)", None),
    ("default: gray, 64 px, stride auto", {}),
    ("stride 1 (every frame kept)", {"stride": 1}),
    ("stride 4", {"stride": 4}),
    ("color, stride auto", {"color": True}),
    ("roi 800x800 + size 128x128", {"roi": [560, 140, 800, 800], "size": [128, 128]}),
]


def generate(path: Path, seconds: float, fps: float, w: int = 1920, h: int = 1080) -> float:
    import cv2
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    if not writer.isOpened():
        raise SystemExit(f"OpenCV cannot write mp4v to {path}")
    rng = np.random.default_rng(0)
    # a fixed texture makes the encoder (and later the decoder) do real work, unlike black frames
    background = cv2.GaussianBlur(rng.integers(0, 256, (h, w, 3), dtype=np.uint8), (5, 5), 0)
    background = (background // 2 + 40).astype(np.uint8)
    t0 = time.perf_counter()
    n = int(round(seconds * fps))
    for i in range(n):
        f = background.copy()
        angle = 0.6 * np.exp(-0.02 * i / fps) * np.sin(2 * np.pi * i / fps / 1.6)  # 1.6 s period
        cx = int(w / 2 + 700 * np.sin(angle))
        cy = int(100 + 700 * np.cos(angle))
        cv2.line(f, (w // 2, 100), (cx, cy), (200, 200, 200), 3)
        cv2.circle(f, (cx, cy), 60, (40, 60, 230), -1)
        writer.write(f)
    writer.release()
    return time.perf_counter() - t0


def run_child(video: str, kwargs: dict | None) -> dict:
    env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "2"))
    out = subprocess.run([sys.executable, "-c", CHILD, video if kwargs is not None else "-",
                          json.dumps(kwargs or {})], capture_output=True, text=True, env=env,
                         cwd=HERE.parent)
    if out.returncode != 0:
        raise SystemExit(f"child failed: {out.stderr.strip()}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--fps", type=float, default=60.0)
    ap.add_argument("--video", type=Path, default=Path("/tmp/fitode-bench/fullhd_60fps.mp4"))
    ap.add_argument("--keep", action="store_true", help="keep the generated video")
    ap.add_argument("--reuse", action="store_true", help="use the video at --video if it exists")
    ap.add_argument("--out", type=Path, default=HERE / "out" / "video_memory.json")
    args = ap.parse_args()

    args.video.parent.mkdir(parents=True, exist_ok=True)
    reuse = args.reuse and args.video.exists()
    gen_s = 0.0 if reuse else generate(args.video, args.seconds, args.fps)
    size_mb = args.video.stat().st_size / 2**20
    n = int(round(args.seconds * args.fps))
    full_gb = n * 1080 * 1920 * 3 / 2**30
    print(f"{'reused' if reuse else 'generated'} {args.video} ({n} frames 1920x1080 at {args.fps:g} fps, {size_mb:.0f} MB) "
          f"in {gen_s:.0f} s; holding every frame in full would take {full_gb:.1f} GiB (uint8 BGR)")

    rows = []
    for name, kwargs in SETTINGS:
        res = run_child(str(args.video), kwargs)
        res["setting"], res["kwargs"] = name, kwargs
        rows.append(res)
        shape = "x".join(map(str, res["shape"])) if res["shape"] else "-"
        print(f"  {name:<36} peak RSS {res['maxrss_mb']:7.0f} MB   wall {res['wall_s']:6.1f} s   "
              f"cpu {res['cpu_s']:6.1f} s   "
              f"frames {shape:<16} stride {res['stride']}", flush=True)

    base = rows[0]["maxrss_mb"]
    print()
    print(f"| setting | peak RSS (MB) | above baseline (MB) | kept frames (MB) | wall (s) | "
          f"CPU (s) | frames/s (wall) | kept shape | stride |")
    print("|---|---:|---:|---:|---:|---:|---:|---|---:|")
    for r in rows:
        fps_read = n / r["wall_s"] if r["frames"] else float("nan")
        shape = "x".join(map(str, r["shape"])) if r["shape"] else "-"
        print(f"| {r['setting']} | {r['maxrss_mb']:.0f} | {r['maxrss_mb'] - base:.0f} | "
              f"{r.get('frames_mb', 0):.0f} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | {fps_read:.0f} | "
              f"{shape} | "
              f"{r['stride'] or '-'} |")
    auto = next(r for r in rows if r["setting"].startswith("default"))
    print(f"\nauto stride: {auto['reason']}")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_json({
        "video": {"path": str(args.video), "frames": n, "fps": args.fps, "size": [1080, 1920],
                  "codec": "mp4v", "file_mb": size_mb, "generate_s": gen_s,
                  "full_resolution_gib": full_gb},
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                    "load_average": os.getloadavg()},
        "rows": rows}, args.out, indent=2)
    print(f"wrote {args.out}")
    if not (args.keep or reuse):
        args.video.unlink()


if __name__ == "__main__":
    main()
