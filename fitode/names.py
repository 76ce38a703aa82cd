"""Constant names and NAME=VALUE lists as a user types them (`--const g=9.81,L=1`, `--free g`).

Below both the command line (fitode.options) and equation files (fitode.eqfile), which read them.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterable

from fitode.errors import FitodeError

_NAME = re.compile(r"[A-Za-z_][A-Za-z_0-9]*")


def _items(items: Iterable[str] | str | None) -> list[str]:
    """Flatten repeated flags and comma lists: ["g=9.81,L=1", "z=0"] -> ["g=9.81", "L=1", "z=0"]."""
    if items is None:
        return []
    if isinstance(items, str):
        items = [items]
    out = []
    for item in items:
        out += [part.strip() for part in str(item).split(",") if part.strip()]
    return out


def parse_assignments(items: Iterable[str] | str | None, flag: str = "--const") -> dict[str, float]:
    """["g=9.81", "L=1,z=0.1"] -> {"g": 9.81, "L": 1.0, "z": 0.1}; FitodeError on a malformed item.

    A name given twice with different values is an error; values must be finite numbers.
    """
    out: dict[str, float] = {}
    for item in _items(items):
        name, eq, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not eq or not name or not value:
            raise FitodeError(f"{flag} expects NAME=VALUE, got {item!r}")
        if not _NAME.fullmatch(name):
            raise FitodeError(f"{flag}: {name!r} is not a valid name")
        number = finite_number(value, f"{flag} {name}: {value!r} is not a number (write NAME=VALUE, e.g. g=9.81)",
                               f"{flag} {name}: the value must be finite, got {value}")
        if name in out and out[name] != number:
            raise FitodeError(f"{flag}: {name} is given twice ({out[name]:g} and {number:g})")
        out[name] = number
    return out


def finite_number(text: str, not_number: str, not_finite: str, error: type[FitodeError] = FitodeError) -> float:
    """float(text), or `error` with the message that says what was wrong: not a number, or inf/nan."""
    try:
        number = float(text)
    except ValueError:
        raise error(not_number) from None
    if not math.isfinite(number):
        raise error(not_finite)
    return number


def parse_names(items: Iterable[str] | str | None, flag: str = "--free") -> list[str]:
    """["g", "L,z"] -> ["g", "L", "z"] (duplicates dropped, order kept); FitodeError on a bad name."""
    out: list[str] = []
    for item in _items(items):
        if not _NAME.fullmatch(item):
            raise FitodeError(f"{flag} expects a constant's name, got {item!r}")
        if item not in out:
            out.append(item)
    return out
