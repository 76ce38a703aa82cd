"""docs/library.md runs as it stands: every ```python block, in order, in one namespace, in an empty folder."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "library.md"


def blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)


def test_the_page_has_its_four_walks():
    text = DOC.read_text()
    for heading in ("## Fitting a clip", "## A calibrated clip", "## Which equation", "## A batch"):
        assert heading in text
    assert len(blocks()) == 5


@pytest.mark.slow  # four small fits, a comparison and a batch of three 40-frame clips
def test_library_doc_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "library_doc"}
    for i, block in enumerate(blocks()):
        exec(compile(block, f"{DOC.name} block {i + 1}", "exec"), ns)
    out = capsys.readouterr().out
    # the walks did what the page says they do
    assert "estimates (mean over" in out and "TRUSTED" in out  # print(result) is the table
    assert {p.name for p in (tmp_path / "swing-run").iterdir()} >= {"result.json", "fit.json", "estimates.csv",
                                                                   "track.csv", "latent.png"}
    assert ns["drain"].parameters["k"].calibrated
    assert ns["comparison"]["preferred"] == "theta'' = -g/L*sin(theta) - zeta*theta'"
    rows = ns["rows"]
    assert len(rows) == 3 and all(r["gamma.low"] and r["gamma.high"] and r["gamma.verdict"] for r in rows)
    for r in rows:  # each lamp's rate near its truth (a 95% interval may miss it, one time in twenty)
        assert abs(float(r["gamma.rel_error"])) < 0.05, r
        assert float(r["gamma.low"]) < float(r["gamma"]) < float(r["gamma.high"]), r
    assert all(g["gamma.pooled_low"] for g in ns["groups"])
