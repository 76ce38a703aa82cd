"""numpy's floating-point warnings during a fit, kept as findings instead of terminal noise.

An overflow in exp or an invalid value in a square root (a state that never shows in the video,
constants far from the data) is printed by numpy as a RuntimeWarning with a source line the
user cannot act on, in the middle of the progress lines. Within `kept()` they are recorded,
counted by message, and become one warning line each in the result (result.warnings, the
table's `warning:` lines), saying where they came from.
"""
from __future__ import annotations

import collections
import contextlib
import warnings
from pathlib import Path
from typing import Iterator


class Kept:
    """The RuntimeWarnings seen in a `kept()` block, by message and where it arose."""

    def __init__(self) -> None:
        self.seen: collections.Counter = collections.Counter()

    def lines(self) -> list[str]:
        return [f"numpy warned {n} time{'s' if n > 1 else ''} during the fit: {msg} (in {where}); a state that "
                "never shows in the video, or constants far from what the clip shows, overflow the numbers: "
                "look at latent.png and the verdicts" for (msg, where), n in self.seen.items()]


@contextlib.contextmanager
def kept() -> Iterator[Kept]:
    out = Kept()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        try:
            yield out
        finally:
            for w in caught:
                if issubclass(w.category, RuntimeWarning):
                    out.seen[(str(w.message), f"{Path(w.filename).parent.name}/{Path(w.filename).name}")] += 1
                else:  # not ours to judge: shown as Python would have
                    warnings.showwarning(w.message, w.category, w.filename, w.lineno)
