"""What a fit returns: estimates, their spread, every run's history, the latent and the rollout."""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .history import History

from fitode.jsonio import to_jsonable, write_json


@dataclass
class Estimate:
    """A constant's estimate: value and std (over the restarts it comes from) in physical units
    where calibrated, else the latent's; latent_value: the value before calibration; interval:
    its 95% interval from what limits it (fitode.train.interval)."""

    value: float
    std: float
    n_runs: int
    unit: str | None = None
    calibrated: bool = False
    latent_value: float | None = None
    interval: list[float] | None = None  # [low, high], 95% (fitode.train.interval); None where none was made


@dataclass
class RunRecord:
    """One restart: where it started, where it ended, and how it got there."""

    index: int
    seed: int
    init: dict[str, float]
    final: dict[str, float]
    loss: float
    steps: int
    status: str  # "ok" | "failed" | "interrupted"
    error: str | None = None
    converged: bool = False
    wall_s: float = 0.0
    history: History = field(default_factory=History)
    stop_reason: str = ""  # "converged" | "max_steps" | "non-finite" | "interrupted"
    gauge: dict[str, dict[str, float]] = field(default_factory=dict)  # state -> {"scale", "offset"}
    score: float | None = None  # does its latent tell the frames apart (fitode.train.score); None: not scored
    miss: float | None = None  # final window prediction error over the latent's variance (scale-free, no KL)
    origin: str = ""  # where its start came from: "user", "equation file", "data" or "spread"
    # final values in the best run's orientation of the latent: a constant that changes sign with
    # the state (g in d'' = g) is negated where this run's latent points the other way
    aligned: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.history, History):  # a plain dict, as JSON and hand-built records give it
            self.history = History.from_dict(self.history)

    def value(self, name: str) -> float:
        """The final value of a constant, comparable across restarts (see aligned)."""
        return self.aligned.get(name, self.final[name])

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "RunRecord":
        known = {f for f in cls.__dataclass_fields__}
        return cls(**{k: v for k, v in d.items() if k in known})


@dataclass
class FitResult:
    """The outcome of a fit (fitode.fit returns it as a fitode.Result, which adds the table,
    intervals at any level, a DataFrame, a figure and the output folder).

    parameters: the estimate of each learnable constant (an Estimate: the mean over the selected
        runs, their spread `std` (standard deviation over the selected runs, 0 for one: how alike
        the restarts ended, no error bar), n_runs, unit, calibrated, latent_value and the 95%
        `interval`, the uncertainty).
    runs: every restart (RunRecord: where it started and ended, loss, steps, status, history).
    selected: indices of the runs the estimate comes from: the finite runs whose final loss is
        within `selection_factor` of the lowest final loss.
    best: the selected run with the lowest loss: its latent, rollout and gauge are the ones kept.
    latent: (T, d) the best run's reading of every frame (encoded or measured), training range and beyond.
    rollout: (T, d) the physics rollout from the first frames with the best run's constants.
    time: (T,) seconds from the first frame; frames at index >= train_frames were not trained on.
    train_frames: the frames trained on (the first ones); dt: seconds between frames.
    states: the equation's states in order; equation: its text; fixed: its fixed constants.
    settings: the training options as resolved (TrainConfig.as_dict, plus the steps per frame a
        measured path needed); selection_factor: a run within this factor of the lowest loss is selected.
    meta: what the fit found out about the clip, by key (written by train.trainer.fit_frames unless said):
        plan: the FitPlan's choices with their reasons; measured: the observation measures the
        state (a path, not a learned latent); bends: the path can bend where the frames do not hold
        it (a learned latent, a light read linearly), so its interval takes the bends' share; bend_floor: the least share of the value that is (None:
        train.interval.ENCODER_FLOOR); physical_units: every state is in a unit of its own
        (radians, px or m), so no constant waits for a calibration; units: state -> the unit its
        measured path was fitted in ("px", or "m" with a scale stick; {} for a learned latent);
        length: how a length read (unit, frame_scale: source pixels per frame pixel,
        metres_per_px and relative_std of a scale stick; None without units); subspace: the
        observation's one-line note; rank: its input columns; gauge: state -> how it follows from
        the latent; own_units: constants taken from the best run alone (each run read the path in
        units of its own); left_out: run -> why it is not in the estimate; measurement: what was
        measured, to draw (observe.drawing; in source pixels after pipeline.source_measurement);
        stretch: the frames the path was fitted on and why (start_frame, end_frame, start_s,
        end_s, reason, source); direct: the path was fitted directly (train/direct.py);
        direct_failed: why not, where the encoder trained instead; trajectory: the measured and
        fitted path on the stretch, the fit's values, errors and misfit (read by the interval);
        interrupted: training was stopped (Ctrl-C); stopped: stopped after training
        (fitode.interrupted); calibration_skipped: why --calibrate was not applied (fitode.api);
        comparison: every candidate's numbers where several were compared (fitode.compare);
        input: the clip as read (pipeline.run_video).
    verdicts: name -> {"verdict": trusted | ambiguous | not trustworthy, "reason", "other_reasons"}.
    checks: the numbers behind the verdicts (interval, consistency, integrator, every finding).
    warnings: the assessment's findings that are no verdict's headline, and numpy's warnings.
    notes: what happened to the restarts (left out, failed), no judgement.
    calibration: the calibration applied (maps, converted constants, calibrated trajectories), or None.
    """

    parameters: dict[str, Estimate]
    runs: list[RunRecord]
    selected: list[int]
    best: int
    latent: np.ndarray
    rollout: np.ndarray
    time: np.ndarray
    train_frames: int
    dt: float
    states: list[str]
    equation: str
    fixed: dict[str, float]
    settings: dict[str, Any]
    selection_factor: float = 1.5
    meta: dict[str, Any] = field(default_factory=dict)
    verdicts: dict[str, dict[str, str]] = field(default_factory=dict)  # name -> {"verdict", "reason"}
    checks: dict[str, Any] = field(default_factory=dict)  # the numbers behind the verdicts
    warnings: list[str] = field(default_factory=list)  # the assessment's findings that are no verdict's headline
    notes: list[str] = field(default_factory=list)  # what happened to the restarts, no judgement
    calibration: dict[str, Any] | None = None  # the calibration applied (fitode.calibrate), with its trajectories

    @property
    def values(self) -> dict[str, float]:
        return {k: e.value for k, e in self.parameters.items()}

    @property
    def failed(self) -> list[int]:
        return [r.index for r in self.runs if r.status != "ok"]

    def to_dict(self) -> dict[str, Any]:
        d = {
            "parameters": {k: asdict(v) for k, v in self.parameters.items()},
            "selected": self.selected,
            "best": self.best,
            "selection_factor": self.selection_factor,
            "equation": self.equation,
            "states": self.states,
            "fixed": self.fixed,
            "dt": self.dt,
            "train_frames": self.train_frames,
            "time": self.time.tolist(),
            "latent": self.latent.tolist(),
            "rollout": self.rollout.tolist(),
            "runs": [asdict(r) for r in self.runs],
            "settings": self.settings,
            "meta": self.meta,
            "verdicts": self.verdicts,
            "checks": self.checks,
            "warnings": self.warnings,
            "notes": self.notes,
            "calibration": self.calibration,
        }
        return to_jsonable(d)

    def save_json(self, path: str | Path) -> Path:
        """Everything (to_dict) as JSON at path, as fit.json; back with load."""
        return write_json(self.to_dict(), path)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "FitResult":
        return cls(
            parameters={k: Estimate(**v) for k, v in d["parameters"].items()},
            runs=[RunRecord.from_dict(r) for r in d["runs"]],
            selected=list(d["selected"]),
            best=int(d["best"]),
            latent=np.asarray(d["latent"], dtype=float),
            rollout=np.asarray(d["rollout"], dtype=float),
            time=np.asarray(d["time"], dtype=float),
            train_frames=int(d["train_frames"]),
            dt=float(d["dt"]),
            states=list(d["states"]),
            equation=d["equation"],
            fixed=dict(d["fixed"]),
            settings=dict(d["settings"]),
            selection_factor=float(d.get("selection_factor", 1.5)),
            meta=dict(d.get("meta", {})),
            verdicts=dict(d.get("verdicts", {})),
            checks=dict(d.get("checks", {})),
            warnings=list(d.get("warnings", [])),
            notes=list(d.get("notes", [])),
            calibration=d.get("calibration"),
        )

    @classmethod
    def load(cls, path: str | Path) -> "FitResult":
        return cls.from_dict(json.loads(Path(path).read_text()))

    def predict(self, n_frames: int, start: int = 0, substeps: int | None = None) -> np.ndarray:
        """Physics prediction of the latent for n_frames frames from frame `start` on.

        The rollout starts from the encoded latent of the first frames at `start` and uses the
        estimated constants, so it runs past the end of the training range (and of the video):
        compare it with `latent[start:]` to see how well the fit extrapolates. Returns (n_frames, d).
        """
        import torch

        from fitode.codegen import PhysicsBlock
        from fitode.eqparse import parse

        system = parse(self.equation, fix=self.fixed, free=list(self.parameters))
        block = PhysicsBlock(system, integrator=self.settings.get("integrator", "rk4"),
                             substeps=substeps or self.settings.get("substeps", 1), dtype=torch.float64)
        block.set_constants(self.values)
        if not 0 <= start <= len(self.latent) - block.n_context:
            raise ValueError(f"start must leave {block.n_context} encoded frames to begin from")
        # the equation sees the state x = s*z + b of the best run's gauge, the plots the latent z
        gauge = self.runs[self.best].gauge if self.runs else {}
        s = np.array([gauge.get(st, {}).get("scale", 1.0) for st in self.states])
        b = np.array([gauge.get(st, {}).get("offset", 0.0) for st in self.states])
        head = torch.as_tensor(self.latent[start: start + block.n_context] * s + b, dtype=torch.float64)
        with torch.no_grad():
            return (block(head[None], n_frames, self.dt)[0].numpy() - b) / s
