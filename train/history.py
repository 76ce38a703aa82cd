"""The step history of one run: what the trainer records, the pipeline keeps, the plots draw."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping


@dataclass
class History:
    """Per optimisation step: the loss, its two parts and every learnable constant."""

    step: list[int] = field(default_factory=list)
    loss: list[float] = field(default_factory=list)
    mse: list[float] = field(default_factory=list)
    kl: list[float] = field(default_factory=list)
    constants: dict[str, list[float]] = field(default_factory=dict)

    @classmethod
    def for_constants(cls, names) -> "History":
        return cls(constants={n: [] for n in names})

    def append(self, step: int, loss: float, mse: float, kl: float, constants: Mapping[str, float]) -> None:
        self.step.append(int(step))
        self.loss.append(float(loss))
        self.mse.append(float(mse))
        self.kl.append(float(kl))
        for n, series in self.constants.items():
            series.append(float(constants.get(n, float("nan"))))

    def __len__(self) -> int:
        return len(self.step)

    def to_dict(self) -> dict[str, Any]:
        return {"step": list(self.step), "loss": list(self.loss), "mse": list(self.mse), "kl": list(self.kl),
                "constants": {n: list(v) for n, v in self.constants.items()}}

    def thinned(self, every: int = 10) -> "History":
        """Every `every`-th step and the last, to keep a benchmark's JSON small."""
        keep = list(range(0, len(self), max(int(every), 1)))
        if keep and keep[-1] != len(self) - 1:
            keep.append(len(self) - 1)

        def pick(series):
            return [series[i] for i in keep]
        return History(pick(self.step), pick(self.loss), pick(self.mse), pick(self.kl),
                       {n: pick(v) for n, v in self.constants.items()})

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "History":
        d = d or {}
        return cls(list(d.get("step", [])), list(d.get("loss", [])), list(d.get("mse", [])), list(d.get("kl", [])),
                   {n: list(v) for n, v in (d.get("constants") or {}).items()})
