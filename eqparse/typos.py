"""Names that look like a mistyped state variable (`sin(teta)` where the state is theta).

A name that is not a state becomes a learnable constant; a typo then fits silently and the run
ends blaming the video. These rules decide when a constant's name is close enough to a state to
be a likely typo, while leaving deliberate names alone: Greek letters' names (zeta beside the
state beta), indexed families (theta0 beside theta, x1 beside x2) and one- or two-letter names
(k beside x), which are too short for a distance to mean anything.
"""
from __future__ import annotations

import re

GREEK = frozenset((
    "alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota", "kappa", "lambda", "mu",
    "nu", "xi", "omicron", "pi", "rho", "sigma", "tau", "upsilon", "phi", "chi", "psi", "omega",
))
MIN_LENGTH = 3
"""Shorter names are never typos of each other: one letter apart is every pair of single letters."""


def edit_distance(a: str, b: str) -> int:
    """Optimal string alignment distance: insertions, deletions, substitutions and adjacent swaps."""
    prev2: list[int] = []
    prev = list(range(len(b) + 1))
    for i in range(1, len(a) + 1):
        cur = [i] + [0] * len(b)
        for j in range(1, len(b) + 1):
            cost = a[i - 1] != b[j - 1]
            cur[j] = min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost)
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                cur[j] = min(cur[j], prev2[j - 2] + 1)
        prev2, prev = prev, cur
    return prev[-1]


def _stem(name: str) -> str:
    return re.sub(r"[_\d]+$", "", name)


def likely_typo(name: str, state: str) -> bool:
    """Is the constant `name` within edit distance 1 (states up to 4 letters) or 2 of `state`,
    and not a deliberate relative of it?"""
    if name == state or min(len(name), len(state)) < MIN_LENGTH:
        return False
    if name.lower() in GREEK and name.lower() != state.lower():  # zeta beside beta: two letters, both meant
        return False
    if _stem(name) == _stem(state):  # theta0, theta_1 beside theta: an indexed family
        return False
    return edit_distance(name, state) <= (1 if len(state) <= 4 else 2)


def nearest(name: str, candidates: list[str] | tuple[str, ...]) -> str:
    """The candidate closest to name (the first of equals)."""
    return min(candidates, key=lambda c: edit_distance(name.lower(), c.lower()))
