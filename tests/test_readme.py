"""The README's quick start stays true: the lines its command prints before training (what fitode
understood and chose) are those in the README's transcript, which docs/quickstart.py writes."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def quickstart():
    spec = importlib.util.spec_from_file_location("quickstart", ROOT / "docs" / "quickstart.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_readme_shows_the_quick_start_command_and_a_transcript_with_its_result():
    qs = quickstart()
    readme = (ROOT / "README.md").read_text()
    assert "    ./setup.sh && .venv/bin/" + " ".join(qs.COMMAND) in readme
    assert "    ./setup.sh && .venv/bin/python -m pytest" in readme
    lines = qs.transcript_block(readme)
    head = qs.header(lines)
    assert head and head[0].startswith("fitode ") and len(head) < len(lines)
    assert any(line.strip().startswith("L ") and "TRUSTED" in line for line in lines)
    assert (ROOT / "docs" / "quickstart.png").stat().st_size < 100_000  # small, committed


@pytest.mark.slow
def test_the_quick_start_prints_the_header_the_readme_shows(tmp_path):
    """Runs the quick start's command up to its first training step or its first restart's line
    (a measured path is fitted directly, with no training step): the header is printed before."""
    from fitode.pipeline import run_job

    qs = quickstart()
    printed: list[str] = []

    def stop(_info=None):
        raise KeyboardInterrupt

    def log(line):
        printed.append(line)
        if qs.header([line]) != [line]:  # the first line after the header
            stop()

    video, _, eq_file = qs.COMMAND[1:]
    with pytest.raises(KeyboardInterrupt):
        run_job(ROOT / video, tmp_path / "qs", eq_file=str(ROOT / eq_file), log=log, callback=stop)
    shown = qs.header(qs.transcript_block((ROOT / "README.md").read_text()))
    # the input line names the video as the command gives it, relative to the repository
    printed = [line.replace(str(ROOT) + "/", "") for line in printed]
    assert printed[:len(shown)] == shown
