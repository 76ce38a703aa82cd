"""The `fitode` command: `fitode VIDEO --eq ...` runs a fit; other verbs live beside it.

Each verb is a module `fitode.cmd_<verb>` with `add_arguments(parser)` and
`run(args) -> int`. A first argument that is not a verb means the main job (`run`).
"""
from __future__ import annotations

import argparse
import contextlib
import difflib
import gc
import importlib
import re
import signal
import sys
import threading

from fitode.errors import FitodeError

VERBS = {
    "run": "fit a video (the default: `fitode VIDEO --eq ...`)",
    "check": "parse an equation and report what a video can measure",
    "codegen": "print the generated torch code for an equation",
    "synth": "render a synthetic video of an equation",
    "bench": "run a benchmark and print its table",
    "batch": "fit many videos listed in a manifest",
}


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad flags in one line with status 2 (argparse prints usage too), and
    takes no abbreviation: `--restart 2` is not silently `--restarts 2`, it gets the did-you-mean."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)  # the sub-verbs' parsers (add_parser) too
        super().__init__(*args, **kwargs)

    def parse_known_args(self, args=None, namespace=None):
        # before argparse: it reports a missing required flag first, so `--sytem pendulum`
        # would say only that one of --eq, --eq-file, --system is required
        self._check_flags(sys.argv[1:] if args is None else list(args))
        return super().parse_known_args(args, namespace)

    def _check_flags(self, args: list[str]) -> None:
        if self._subparsers is not None:  # `fitode synth paper ...`: the sub-verb's parser checks its own flags
            return
        if any(a.nargs == argparse.REMAINDER for a in self._actions):
            # `fitode bench NAME --quick`: what follows the positionals is the benchmark's to check
            first = next((i for i, a in enumerate(args) if not a.startswith("-")), len(args))
            args = args[:first]
        known = [s for s in self._option_string_actions if s.startswith("--")]
        for arg in args:
            if arg == "--":
                break
            flag = arg.split("=", 1)[0]
            if not re.fullmatch(r"--[A-Za-z][\w-]*", flag) or flag in known:
                continue
            longer = [k for k in known if k.startswith(flag)]
            close = longer[:1] if len(longer) == 1 else difflib.get_close_matches(flag, known, n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]}?)" if close else f" (see {self.prog} -h)"
            self.error(f"unknown flag {flag}{hint}")

    def error(self, message: str) -> None:  # noqa: D401
        # main() already prefixes "fitode: error:"; name the verb only when there is one
        raise FitodeError(message if self.prog == "fitode" else f"{self.prog}: {message}")


def build_parser(verb: str) -> argparse.ArgumentParser:
    parser = _Parser(prog=f"fitode {verb}" if verb != "run" else "fitode", description=VERBS[verb])
    _module(verb).add_arguments(parser)
    return parser


def _module(verb: str):
    return importlib.import_module(f"fitode.cmd_{verb}")


def _usage() -> str:
    lines = ["usage: fitode VIDEO --eq TEXT [options]   (fit a video; `fitode run -h` for options)",
             "       fitode VERB [options]", "", "verbs:"]
    lines += [f"  {v:<8} {h}" for v, h in VERBS.items()]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0 if argv else 2
    if argv[0] == "--version":
        from fitode._version import __version__
        print(f"fitode {__version__}")
        return 0
    verb = argv[0] if argv[0] in VERBS else "run"
    rest = argv[1:] if argv[0] in VERBS else argv
    with _sigterm_as_interrupt() as term:
        try:
            args = build_parser(verb).parse_args(rest)
            return int(_module(verb).run(args) or 0)
        except FitodeError as exc:
            print(f"fitode: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("fitode: terminated" if term else "fitode: interrupted", file=sys.stderr)
            return 128 + signal.SIGTERM if term else 130


def entry(argv: list[str] | None = None) -> int:
    """The process's entry (the `fitode` command and `python -m fitode`): main, then the objects it
    leaves frozen out of the collector, so that the interpreter's teardown does not walk every
    object torch, sympy and matplotlib made (about a second of a short run's wall time on this
    project's 2-core machine; atexit handlers and open files are closed as before). The collector
    runs less often meanwhile: the imports alone made 700 of a short run's collections at the
    default threshold (0.6 s of its 7 s), 50 at this one (0.25 s), with the same peak memory on the
    README's example. Not in main: a caller that runs main many times in one process (the tests)
    keeps its collector as it set it; bench/speed_clip.py times a process run through here."""
    gc.set_threshold(10_000, 20, 20)
    code = main(argv)
    gc.freeze()
    return code


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM (a scheduler's or `kill`'s stop) raises KeyboardInterrupt in the main thread, so it
    takes Ctrl-C's path: a run leaves its folder marked interrupted, a batch stops its workers and
    writes a consistent summary. The list it yields is non-empty once SIGTERM arrived.
    """
    term: list[int] = []
    if threading.current_thread() is not threading.main_thread():  # signal.signal works only there
        yield term
        return

    def handler(signum, frame):
        if term:  # a second SIGTERM must not cut short the cleanup that the first one started
            return
        term.append(signum)
        raise KeyboardInterrupt

    # a Python handler, not SIG_IGN, after the first signal: an ignored signal stays ignored across
    # exec, so processes started during the cleanup could no longer be terminated
    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield term
    finally:
        if previous is not None:  # None: a handler not set from Python, which cannot be restored
            signal.signal(signal.SIGTERM, previous)  # main() is also called in-process (tests, scripts)


if __name__ == "__main__":
    sys.exit(main())
