"""fitode.fit on a video path: the command line's reader and checks, the command line's numbers."""
from __future__ import annotations

import inspect
import json
import subprocess
import sys
from pathlib import Path

import pytest

import fitode
from fitode.cli import main
from fitode.errors import ConfigError, FitodeError
from fitode.examples.make_example import decay_values, render_glow, write_mp4

EQ = "I' = -gamma*I"
TRAIN = dict(restarts=2, max_steps=10, seed=3)


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("fitpath")
    return write_mp4(folder / "glow.mp4", render_glow(decay_values(50, 10.0, 0.5), size=16), 10.0)


@pytest.mark.slow  # three tiny fits, about 10 s
def test_a_path_gives_the_numbers_of_the_command_line(video, tmp_path):
    flags = ["--start", "0.5", "--end", "4.5", "--roi", "0,0,16,12", "--size", "12x9", "--stride", "2",
             "--calibrate", "I(0.5)=1; I(4)=0.2"]
    out = tmp_path / "cli"
    assert main([str(video), "--eq", EQ, "--restarts", "2", "--max-steps", "10", "--seed", "3",
                 "--out", str(out), "--quiet", *flags]) == 0
    cli = json.loads((out / "result.json").read_text())
    api = fitode.fit(str(video), eq=EQ, start=0.5, end=4.5, roi="0,0,16,12", size="12x9", stride=2,
                     calibrate="I(0.5)=1; I(4)=0.2", progress=False, **TRAIN)
    assert cli["parameters"]["gamma"]["calibrated"] is api.parameters["gamma"].calibrated
    assert api.parameters["gamma"].value == cli["parameters"]["gamma"]["value"]  # exactly
    assert api.parameters["gamma"].std == cli["parameters"]["gamma"]["std"]
    assert list(api.time) == pytest.approx([t - 0.5 for t in cli["trajectory"]["time"]], abs=1e-12)
    # dt may be given when it agrees with the clip's
    again = fitode.fit(video, dt=0.2, eq=EQ, start=0.5, end=4.5, roi=(0, 0, 16, 12), size=(9, 12), stride=2,
                       calibrate="I(0.5)=1; I(4)=0.2", progress=False, **TRAIN)
    assert again.parameters["gamma"].value == api.parameters["gamma"].value


def test_path_errors_are_one_line(video):
    cases = [
        (dict(dt=0.05), "disagrees with the clip"),
        (dict(time_offset=1.0), "time_offset"),
        (dict(start=9.0), "start"),
        (dict(roi="0,0,99,99"), "roi"),
        (dict(calibrate="I(9)=1; I(10)=0.5"), "outside the clip"),
    ]
    for kwargs, match in cases:
        with pytest.raises(FitodeError, match=match) as e:
            fitode.fit(video, eq=EQ, progress=False, **TRAIN, **kwargs)
        assert "\n" not in str(e.value)
    with pytest.raises(FitodeError, match="no such file"):
        fitode.fit(str(video) + ".missing", eq=EQ, progress=False)


def test_video_options_with_arrays_are_a_config_error():
    import numpy as np
    frames = np.zeros((10, 8, 8))
    for kwargs in (dict(fps=30), dict(roi=(0, 0, 4, 4)), dict(stride=2), dict(color=True), dict(start=1.0)):
        with pytest.raises(ConfigError, match="video path"):
            fitode.fit(frames, 0.1, eq=EQ, progress=False, **kwargs)


def test_help_shows_the_real_signature_without_torch():
    params = inspect.signature(fitode.fit).parameters
    for name in ("frames", "dt", "eq", "system", "eq_file", "const", "observe", "calibrate", "fps", "start",
                 "end", "roi", "size", "stride"):
        assert name in params, name
    assert "video path" in fitode.fit.__doc__ and "restarts" in fitode.fit.__doc__
    code = "import sys, fitode; help(fitode.fit); assert 'torch' not in sys.modules"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={"PAGER": "cat"})
    assert out.returncode == 0, out.stderr
    assert "calibrate" in out.stdout
