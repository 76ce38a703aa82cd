"""The layout keeps its word: no import circle among the project's modules (imports inside
functions count too), and one front door for the command line and the API."""
from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"fitode": "fitode", "eqparse": "fitode.eqparse", "codegen": "fitode.codegen", "train": "fitode.train",
           "equations": "fitode.equations"}


def _modules() -> dict[str, Path]:
    mods = {}
    for folder, package in FOLDERS.items():
        for f in (ROOT / folder).rglob("*.py"):
            parts = list(f.relative_to(ROOT / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join([package, *parts])] = f
    return mods


def _imports(name: str, path: Path, mods: dict[str, Path]) -> set[str]:
    base = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):  # every import, at the top or inside a function
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name in mods)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = base.split(".")
                module = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            subs = {f"{module}.{a.name}" for a in node.names if f"{module}.{a.name}" in mods}
            out.update(subs)
            if len(subs) < len(node.names) and module in mods:
                out.add(module)
    out.discard(name)
    return out


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_import_circle():
    mods = _modules()
    graph = {name: _imports(name, path, mods) for name, path in mods.items()}
    assert _circles(graph) == []


def test_the_circle_finder_finds_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


@pytest.mark.slow  # two tiny fits, a few seconds
def test_the_command_line_and_the_api_run_one_front_door(tmp_path, monkeypatch):
    import fitode
    from fitode import pipeline
    from fitode.cli import main
    from fitode.examples.make_example import decay_values, render_glow, write_mp4

    video = write_mp4(tmp_path / "glow.mp4", render_glow(decay_values(40, 10.0, 0.5), size=16), 10.0)
    calls = []
    original = pipeline.fit_staged

    def spy(*args, **kwargs):
        calls.append(args[1].measurement)
        return original(*args, **kwargs)

    monkeypatch.setattr(pipeline, "fit_staged", spy)
    eq, out = "I' = -gamma*I", tmp_path / "cli"
    assert main([str(video), "--eq", eq, "--restarts", "2", "--max-steps", "10", "--seed", "3", "--out", str(out),
                 "--quiet"]) == 0
    api = fitode.fit(str(video), eq=eq, restarts=2, max_steps=10, seed=3, progress=False)
    assert len(calls) == 2 and all(m is not None for m in calls)
    cli = json.loads((out / "result.json").read_text())
    assert api.parameters["gamma"].value == cli["parameters"]["gamma"]["value"]
