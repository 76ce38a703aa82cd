"""A throw and a slide filmed at 240 fps, fitted in source pixels and, with the ruler in view as a
scale stick, in metres: the constants within 2% of the truth in either unit, trusted. Seeded random
constants; small clips. End-to-end accuracy checks: `pytest -m long`."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import fitode

pytestmark = pytest.mark.long


def _scene(tmp_path, name, setting, *params, size="240x135", seed=5):
    out = tmp_path / f"{name}.mp4"
    subprocess.run([sys.executable, "-m", "fitode", "synth", "scene", name, "--setting", f"{setting:.6g}",
                    "--param", *params, "--fps", "240", "--size", size, "--seed", str(seed), "--out", str(out)]
                   if params else
                   [sys.executable, "-m", "fitode", "synth", "scene", name, "--setting", f"{setting:.6g}",
                    "--fps", "240", "--size", size, "--seed", str(seed), "--out", str(out)],
                   check=True, capture_output=True)
    physical = json.loads(out.with_suffix(".truth.json").read_text())["settings"]["physical"]
    return out, physical


def test_a_flat_throw_gives_g_in_px_and_with_the_ruler_in_metres(tmp_path):
    g = float(np.random.default_rng(31).uniform(5, 15))
    video, ph = _scene(tmp_path, "throw", g, "angle=25")
    first, last = ph["flight_start_frame"] / 240, (ph["flight_end_frame"] - 1) / 240
    ruler = ph["ruler"]
    common = dict(eq="y'' = -g", free=["g"], fps=240, start=first, end=last, restarts=2, progress=False)
    metres = fitode.fit(str(video), scale=(ruler["p1"], ruler["p2"], ruler["metres"]), **common)
    est = metres.parameters["g"]
    assert est.unit == "m/s^2" and abs(est.value / g - 1) < 0.02
    assert metres.verdicts["g"]["verdict"] == "trusted"
    pixels = fitode.fit(str(video), **common)
    est = pixels.parameters["g"]
    assert est.unit == "px/s^2" and abs(est.value / (g * ph["pixels_per_metre"]) - 1) < 0.02
    assert pixels.verdicts["g"]["verdict"] == "trusted"


def test_a_slide_gives_a_in_px_and_with_the_ruler_in_metres(tmp_path):
    alpha = float(np.random.default_rng(32).uniform(20, 35))
    video, ph = _scene(tmp_path, "sliding_block", alpha)
    pixels = fitode.fit(str(video), eq="s'' = a", fps=240, restarts=2, progress=False)
    est = pixels.parameters["a"]
    assert est.unit == "px/s^2" and abs(est.value / (ph["a"] * ph["pixels_per_metre"]) - 1) < 0.02
    assert pixels.verdicts["a"]["verdict"] == "trusted"
    ruler = ph["ruler"]
    metres = fitode.fit(str(video), eq="s'' = a", fps=240, restarts=2, progress=False,
                        scale=f"{ruler['p1'][0]},{ruler['p1'][1]},{ruler['p2'][0]},{ruler['p2'][1]}={ruler['metres']}")
    est = metres.parameters["a"]
    assert est.unit == "m/s^2" and abs(est.value / ph["a"] - 1) < 0.02
