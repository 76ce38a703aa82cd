"""A finding (one check's outcome) and a verdict (the worst finding on a constant): plain data.

Checks anywhere in training make findings; fitode.train.assess turns them into verdicts.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

LEVELS = ("trusted", "ambiguous", "not trustworthy")


@dataclass(frozen=True)
class Finding:
    """One check's outcome: a level and a one-line reason, for every constant or only `names`."""

    level: str
    reason: str
    names: tuple[str, ...] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"level": self.level, "reason": self.reason}
        if self.names is not None:
            out["names"] = list(self.names)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Finding":
        names = d.get("names")
        return cls(d["level"], d["reason"], tuple(names) if names is not None else None)


@dataclass(frozen=True)
class Verdict:
    verdict: str
    reason: str  # the first reason of the worst level, in one line
    others: tuple[str, ...] = ()  # every other reason found, worst first

    def to_dict(self) -> dict:
        return {"verdict": self.verdict, "reason": self.reason, "other_reasons": list(self.others)}
