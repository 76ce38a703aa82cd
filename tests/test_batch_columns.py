"""Every flag of `fitode VIDEO` is a batch manifest column with the same name and checks."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from fitode.batch import ManifestError, load_manifest, run_batch
from fitode.batch.manifest import CLI_ONLY
from fitode.cli import build_parser

EQ = "x'' = -k*x; y'' = -c*y"


def _flags() -> dict[str, str]:
    """dest -> the flag as typed, for every option of `fitode VIDEO` (positional VIDEO included)."""
    parser = build_parser("run")
    return {a.dest: (a.option_strings[-1] if a.option_strings else a.dest) for a in parser._actions}


def test_every_flag_of_fitode_video_is_a_column(tmp_path):
    (tmp_path / "a.json").write_text("{}")
    flags = _flags()
    assert set(CLI_ONLY) <= set(flags), "an exclusion names no flag of `fitode VIDEO`"
    for dest, flag in flags.items():
        if dest in CLI_ONLY or dest in ("video", "eq"):
            continue
        # one column with a value argparse would refuse too: a manifest column that did not exist
        # would be "unknown column" instead of a complaint about its value
        m = tmp_path / f"{dest}.csv"
        m.write_text(f"video,eq,{dest}\na.json,\"{EQ}\",\"@@\"\n")
        with pytest.raises(ManifestError) as err:
            load_manifest(m)
        assert "unknown column" not in str(err.value), f"{flag} has no manifest column '{dest}'"
        if dest in ("eq_file", "system"):
            assert "give the equation once" in str(err.value)
        else:
            assert f"column '{dest}'" in str(err.value), (flag, str(err.value))


def test_the_new_columns_take_the_flags_values(tmp_path):
    (tmp_path / "a.json").write_text("{}")
    m = tmp_path / "m.csv"
    m.write_text("video,eq,observe,const,init,const.c\n"
                 f"a.json,\"{EQ}\",x=position;y=size,c=1,k=3,2\n")
    job, = load_manifest(m).jobs
    assert job.kwargs["observe"] == {"x": "position", "y": "size"}
    assert job.kwargs["const"] == {"c": 2.0}  # the dotted column wins over the text
    assert job.kwargs["init"] == {"k": 3.0}
    for row, message in ((f"a.json,\"{EQ}\",bogus", "column 'observe': unknown observation model"),
                         (f"a.json,\"{EQ}\",x=position", "column 'observe': observe names no model for y")):
        m.write_text(f"video,eq,observe\n{row}\n")
        with pytest.raises(ManifestError, match=message):
            load_manifest(m)


def test_batch_writes_one_estimates_table(tmp_path):
    import test_batch  # the stand-in runner: estimates without a fit
    for name, gamma in (("a.json", 0.5), ("b.json", 0.7)):
        test_batch._video(tmp_path, name, gamma=gamma)
    m = test_batch._csv(tmp_path, [f"a.json,A,{test_batch.EQ},0.5", f"b.json,B,{test_batch.EQ},"])
    out = tmp_path / "out"
    run_batch(m, out, workers=1, runner=test_batch.RUNNER, log=None, defaults={"max_steps": 10})
    rows = list(csv.DictReader((out / "estimates.csv").open()))
    from fitode.tables import BATCH_ESTIMATE_COLUMNS
    assert tuple(rows[0]) == BATCH_ESTIMATE_COLUMNS
    assert [(r["job"], r["constant"]) for r in rows] == [("001-a", "gamma"), ("002-b", "gamma")]
    for r in rows:
        report = json.loads((out / r["job"] / "result.json").read_text())
        assert float(r["value"]) == report["parameters"]["gamma"]["value"]
        assert float(r["restart_spread"]) == report["parameters"]["gamma"]["std"]
        assert Path(r["video"]).name in ("a.json", "b.json")
