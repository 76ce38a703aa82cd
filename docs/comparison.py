"""The four comparisons of docs/comparison.md on the generated clips of tests/test_compare.py:
`.venv/bin/python docs/comparison.py` prints each one's table and verdict line."""
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import fitode  # noqa: E402
from fitode.report import comparison_lines  # noqa: E402
from test_compare import LINEAR, PENDULUM, _ball, _path, _swing  # noqa: E402


def clips():
    yield "a 50-degree swing", *_swing(50)[:2], [LINEAR, PENDULUM], {}
    frames, dt, observe = _swing(5)
    yield "a 5-degree swing", frames, dt, [PENDULUM, LINEAR], {"observe": observe}
    y = _path("y'' = -g - k*y'*abs(y')", {"k": 0.5}, {"y": 0.0, "y'": 0.0}, 90, 1 / 60, 0.0)[:, 0]
    yield ("a fall with strong drag (k = 0.5 /m)", _ball(8 - 25 * y, 30 + 0 * y, 140, 60), 1 / 60,
           ["y'' = -g", "y'' = -g - k*y'*abs(y')"], {"free": ["g"]})
    h = _path("h' = -k*sqrt(h)", {"k": 0.05}, {"h": 0.23}, 200, 1 / 15, 0.0)[:, 0]
    yield "a draining tank", _ball(100 - 400 * h, 40 + 0 * h, 110, 80), 1 / 15, ["h' = -k*h", "h' = -k*sqrt(h)"], {}


for title, frames, dt, eqs, kw in clips():
    result = fitode.fit(frames, dt, eq=eqs, restarts=1, progress=False, **kw)
    print(f"## {title}: {len(frames)} frames")
    print("\n".join(comparison_lines(result.meta["comparison"])))
    print()
