"""`fitode bench NAME [options]`: run one of the benchmarks in the repository's bench/ folder.

    fitode bench --list
    fitode bench paper-synthetic [--quick] [--out DIR] [--workers N] ...
    fitode bench realistic --videos 1
    fitode bench speed
    fitode bench paper-synthetic --help        # that benchmark's own options

The benchmarks are scripts of a fitode source checkout (bench/<name>.py, `-` in NAME read as
`_`), not part of the installed package: they are found through $FITODE_BENCH_DIR, else beside
the package's own source folder (an editable install of a clone), else in ./bench. A script
that defines `add_arguments(parser)` and `run(args)` gets its flags parsed here (bad flags are
one-line errors); one that only has `main(argv)` is called with the remaining arguments.
"""
from __future__ import annotations

import argparse
import ast
import importlib.util
import inspect
import os
import sys
from pathlib import Path

from fitode.errors import FitodeError

ENV = "FITODE_BENCH_DIR"
MARKER = "common.py"  # bench/common.py: tells the benchmarks' folder from any other 'bench'


class BenchError(FitodeError):
    """A benchmark that cannot be found or started (one-line message)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", nargs="?", metavar="NAME", help="the benchmark, e.g. paper-synthetic, realistic, speed")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    parser.add_argument("args", nargs=argparse.REMAINDER, metavar="...",
                        help="the benchmark's own options (fitode bench NAME --help lists them)")


def candidates() -> list[Path]:
    """Where the bench/ folder is looked for, in order."""
    out = []
    env = os.environ.get(ENV)
    if env:
        out.append(Path(env))
    import fitode
    out.append(Path(fitode.__file__).resolve().parent.parent / "bench")
    out.append(Path.cwd() / "bench")
    return out


def find_bench_dir() -> Path:
    env = os.environ.get(ENV)
    if env:
        p = Path(env)
        if not (p / MARKER).is_file():
            raise BenchError(f"${ENV} = {env}: not a fitode bench/ folder (no {MARKER} in it)")
        return p.resolve()
    for p in candidates():
        if (p / MARKER).is_file():
            return p.resolve()
    looked = ", ".join(str(p) for p in dict.fromkeys(candidates()))
    raise BenchError(f"the benchmarks live in the bench/ folder of a fitode source checkout and none was found "
                     f"(looked in {looked}); run from a clone or set ${ENV}")


def available(bench_dir: Path) -> dict[str, str]:
    """name -> first line of its docstring, for every bench/<name>.py except the shared helpers."""
    out = {}
    for path in sorted(bench_dir.glob("*.py")):
        if path.name.startswith("_") or path.name == MARKER:
            continue
        try:
            doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
        except (SyntaxError, UnicodeDecodeError, OSError):
            doc = ""
        first = doc.strip().splitlines()[0] if doc.strip() else ""
        # "paper-synthetic: the paper's ..." -> drop the repeated name
        name = path.stem.replace("_", "-")
        if first.lower().startswith(name + ":"):
            first = first[len(name) + 1:].strip()
        out[name] = first
    return out


def load(bench_dir: Path, name: str):
    """Import bench/<name>.py as a module named after its file (process-pool workers re-import it
    by that name, so the folder goes on sys.path, which the workers inherit)."""
    stem = name.replace("-", "_")
    path = bench_dir / f"{stem}.py"
    if not path.is_file() or stem == Path(MARKER).stem:
        names = ", ".join(available(bench_dir)) or "none"
        raise BenchError(f"no benchmark named '{name}' in {bench_dir} (available: {names})")
    if str(bench_dir) not in sys.path:
        sys.path.insert(0, str(bench_dir))
    if stem in sys.modules and getattr(sys.modules[stem], "__file__", None) == str(path):
        return sys.modules[stem]
    spec = importlib.util.spec_from_file_location(stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[stem] = module
    try:
        spec.loader.exec_module(module)
    except Exception:
        sys.modules.pop(stem, None)
        raise
    return module


def run(args: argparse.Namespace) -> int:
    bench_dir = find_bench_dir()
    if args.list or not args.name:
        if not args.list:
            print("usage: fitode bench NAME [--quick] [--out DIR] [...]; benchmarks:", file=sys.stderr)
        for name, doc in available(bench_dir).items():
            print(f"  {name:<16} {doc}")
        print(f"(in {bench_dir})")
        return 0 if args.list else 2
    module = load(bench_dir, args.name)
    rest = list(args.args)
    if hasattr(module, "add_arguments") and hasattr(module, "run"):
        from fitode.cli import _Parser  # bad flags: one line on stderr, status 2, like every verb

        doc = (module.__doc__ or "").strip().splitlines()
        parser = _Parser(prog=f"fitode bench {args.name}", description=doc[0] if doc else None)
        module.add_arguments(parser)
        return int(module.run(parser.parse_args(rest)) or 0)
    if hasattr(module, "main"):
        saved = sys.argv
        sys.argv = [str(bench_dir / f"{args.name.replace('-', '_')}.py"), *rest]
        try:
            takes_argv = bool(inspect.signature(module.main).parameters)
            status = module.main(rest) if takes_argv else module.main()  # else it reads sys.argv
        finally:
            sys.argv = saved
        return int(status or 0)
    raise BenchError(f"bench/{args.name.replace('-', '_')}.py has neither run(args) nor main(): not a benchmark")
