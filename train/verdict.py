"""A verdict on every estimate: trusted, ambiguous or not trustworthy, with the reason in one line.

The loss alone cannot judge a fit (the harmonic trap, a latent that follows a start-up transient,
pixel noise fitted by an encoder with more weights than frames). The verdict combines what the
trainer can check against the video itself:
- the score of the best restart (fitode.train.score): does its latent tell the frames apart?
- the periods: where the frames repeat, the latent and the equation's own solution (the rollout
  with the estimated constants) must repeat with them;
- activity: the latent must move wherever the frames still change, not only in a transient;
- agreement: the restarts the estimate comes from must agree, and a restart that scored as well
  and fits its latent about as well but ended elsewhere makes the estimate ambiguous;
- one-way motion: a decay, a drain or a fall can be bent by a free encoder into a solution with
  other constants, which no score can see; only a linear readout of few components is trusted;
- what the equation lets a video measure (fitode.eqparse.identify): a constant that enters only
  through a combination, or whose value depends on the latent's units until calibrated.
The worst finding decides: any "not trustworthy" beats "ambiguous", which beats "trusted".
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

import numpy as np

from .score import dominant_period
from .selection import SCORE_MARGIN

LEVELS = ("trusted", "ambiguous", "not trustworthy")
SCORE_MIN = 0.5  # right latents scored 0.78-0.995 on every motion case tried, wrong ones -0.5 to 0.45
PERIOD_TOL = 0.1
AGREE_TOL = 0.05
SETTLED = 0.005  # a constant that moved less than this (relative) over the last MOTION_STEPS steps has settled
MOTION_STEPS = 200
MISS_MAX = 0.05  # window prediction error over the latent's variance: right fits measured 1e-5 to 1e-3
RIVAL_MISS = 10.0  # a restart that scores alike is a rival only if it fits the latent about as well
# (its window error over the latent's variance within this factor: the loss would mix in the KL term,
# which differs between right fits of a one-way motion)
ONE_WAY_RHO = 0.95
ONE_WAY_RANK = 2  # a linear readout of more components than this can bend a one-way trajectory
QUIET = 0.1  # a quarter of the clip where the latent moves less than this fraction of its spread


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


def video_checks(latent: np.ndarray, rollout: np.ndarray, coefs: np.ndarray, dt: float, score: float | None,
                 oscillator: bool, encoder: str = "mlp", rank: int = 0,
                 miss: float | None = None, observation: str = "any",
                 geometric: bool = False) -> tuple[list[Finding], dict[str, float | None]]:
    """Findings that hold for every constant, from the best run's latent and rollout (training
    frames only), the frames' principal components, the encoder's architecture and the rank of
    the signal subspace it read, and the best run's window miss (RunRecord.miss); and the numbers
    behind them. geometric: the latent is a measured position or size read linearly (no score)."""
    findings: list[Finding] = []
    numbers: dict[str, float | None] = {"score": score}
    if not geometric and (score is None or not math.isfinite(score) or score < SCORE_MIN):
        shown = "nan" if score is None or not math.isfinite(score) else f"{score:.2f}"
        findings.append(Finding("not trustworthy", f"no restart's latent tells the frames apart (best score {shown}; "
                                "a latent that follows what the video shows scores above "
                                f"{SCORE_MIN:g}): the object may be out of view, too small, or not moving"))
    numbers["window_miss"] = miss
    if miss is None or not math.isfinite(miss) or miss > MISS_MAX:
        shown = "n/a" if miss is None or not math.isfinite(miss) else f"{100 * miss:.2g}%"
        findings.append(Finding("not trustworthy", f"the equation with these constants does not follow the latent "
                                f"(its window predictions miss by {shown} of the latent's variance)"))
    one_way = _one_way(latent)
    numbers["one_way"] = one_way
    if one_way and encoder != "linear":
        findings.append(Finding("not trustworthy", f"the state changes one way only, and a free ({encoder}) encoder "
                                "can bend a one-way trajectory into a solution with other constants; fit it with "
                                "--encoder linear where the camera sees the state linearly (brightness)"))
    elif one_way and rank > ONE_WAY_RANK:
        findings.append(Finding("ambiguous", f"the state changes one way only, and a linear readout of {rank} "
                                "principal components can still bend it (an object that moves, not one that "
                                "brightens)"))
    t_frames = dominant_period(coefs, dt) if oscillator else None
    t_latent = dominant_period(latent, dt) if oscillator else None
    finite_roll = rollout[np.all(np.isfinite(rollout), axis=1)] if rollout.size else rollout
    t_roll = dominant_period(finite_roll, dt) if oscillator and len(finite_roll) == len(rollout) else None
    numbers.update(period_frames=t_frames, period_latent=t_latent, period_equation=t_roll)
    if t_frames is not None and t_latent is not None and abs(t_latent - t_frames) > PERIOD_TOL * t_frames:
        findings.append(Finding("not trustworthy", f"the latent repeats every {t_latent:.3g} s but the frames every "
                                f"{t_frames:.3g} s: the latent is folded (such as x^2, at twice the frequency)"))
    if t_frames is not None and t_latent is not None and t_roll is None:
        findings.append(Finding("not trustworthy", f"the frames repeat every {t_frames:.3g} s but the equation with "
                                "these constants does not oscillate over the clip"))
    if t_frames is not None and t_roll is not None and abs(t_roll - t_frames) > PERIOD_TOL * t_frames:
        findings.append(Finding("not trustworthy", f"the equation with these constants repeats every {t_roll:.3g} s "
                                f"but the frames every {t_frames:.3g} s"))
    # a measured latent (a centroid, decoded light) cannot follow only a transient: where it
    # slows, the object or the light does (a decay near rest, which still changes many pixels)
    quiet = _quiet_quarter(latent, coefs, dt) if observation == "any" else None
    if quiet is not None:
        findings.append(Finding("not trustworthy", quiet))
    return findings, numbers


def _one_way(latent: np.ndarray) -> bool:
    """True when the latent moves one way over the clip: its rank correlation with time is near 1
    in every dimension (a decay, a drain, a fall), where no score can judge a bend."""
    z = np.asarray(latent, dtype=float)
    if z.ndim == 1:
        z = z[:, None]
    if len(z) < 8 or not np.all(np.isfinite(z)):
        return False
    t = np.arange(len(z), dtype=float)
    ranks = np.argsort(np.argsort(z, axis=0), axis=0).astype(float)
    rho = [abs(np.corrcoef(ranks[:, j], t)[0, 1]) if ranks[:, j].std() > 0 else 0.0 for j in range(z.shape[1])]
    return bool(min(rho) > ONE_WAY_RHO)


def _quiet_quarter(latent: np.ndarray, coefs: np.ndarray, dt: float) -> str | None:
    """A quarter of the clip where the frames change but the latent barely moves."""
    n = len(latent)
    if n < 16:
        return None
    spread_z = float(np.std(latent, axis=0).max())
    spread_f = float(np.sqrt((np.var(coefs, axis=0)).sum()))
    if spread_z <= 0 or spread_f <= 0:
        return None
    for q in range(1, 4):
        part = slice(q * n // 4, (q + 1) * n // 4)
        moves_z = float(np.std(latent[part], axis=0).max()) / spread_z
        moves_f = float(np.sqrt(np.var(coefs[part], axis=0).sum())) / spread_f
        if moves_z < QUIET and moves_f > 3 * QUIET:
            return (f"the latent stops moving after {q * n // 4 * dt:.3g} s while the frames still change: "
                    "it follows only a start-up transient")
    return None


def _motion(run, name: str) -> float | None:
    """Relative change of a constant over the last MOTION_STEPS steps of a run's history."""
    series = run.history.constants.get(name, [])
    if len(series) < 2:
        return None
    now, then = series[-1], series[-1 - min(MOTION_STEPS, len(series) - 1)]  # a short run: since its start
    return abs(now - then) / max(abs(now), 1e-12)


def judge(names: Iterable[str], runs, selected: list[int], estimates: Mapping[str, float],
          findings: list[Finding], analysis=None, calibrated: Iterable[str] = (),
          own_units: Iterable[str] = ()) -> dict[str, Verdict]:
    """The verdict per constant. runs: RunRecords with .index, .status, .final, .loss, .score,
    .converged; analysis: the equation's IdentifiabilityReport (None: not judged on it);
    own_units: constants whose restarts read one measured path in units of their own, so their
    values are the best run's and are not compared between restarts."""
    calibrated, own_units = set(calibrated), set(own_units)
    by_index = {r.index: r for r in runs}
    sel = [by_index[i] for i in selected]
    scores = [r.score for r in sel if r.score is not None and math.isfinite(r.score)]
    best_score = max(scores) if scores else None
    out = {}
    for name in names:
        value = estimates[name]
        found: list[Finding] = [f for f in findings if f.names is None or name in f.names]
        if analysis is not None:
            c = analysis[name]
            if not c.separable:
                what = f"only {c.combination}" if c.combination else "no value for it alone"
                found.append(Finding("not trustworthy", f"the equation lets a video measure {what}"))
            elif c.scale == "dependent" and name not in calibrated:
                found.append(Finding("not trustworthy", "its value depends on the latent's arbitrary units; "
                                     "give --calibrate with known values of the state"))
        vals = [r.value(name) for r in sel if name in r.final]
        if len(vals) > 1 and name not in own_units and np.std(vals) > AGREE_TOL * max(abs(value), 1e-12):
            found.append(Finding("ambiguous", "the selected restarts disagree: "
                                 + ", ".join(f"{v:.4g}" for v in vals)))
        misses = [r.miss for r in sel if r.miss is not None]
        best_miss = min(misses) if misses else math.inf
        # a measured latent (no scores) is the same line for every restart, so the loss compares
        # them directly: the restarts left out fit it worse, and none is a rival
        rivals = [r for r in runs if r.index not in selected and r.status == "ok" and name in r.final
                  and best_score is not None and r.score is not None and r.score >= best_score - SCORE_MARGIN
                  and (r.miss is None or r.miss <= RIVAL_MISS * best_miss)
                  and abs(r.value(name) - value) > AGREE_TOL * max(abs(value), 1e-12)]
        if rivals:
            found.append(Finding("ambiguous", "restarts that tell the frames apart as well ended elsewhere: "
                                 + "; ".join(f"run {r.index + 1} at {r.value(name):.4g} (score {r.score:.2f}, "
                                             f"loss {r.loss:.3g})" for r in rivals)))
        moving = [m for m in (_motion(r, name) for r in sel if not r.converged) if m is not None]
        if moving and min(moving) > SETTLED:
            found.append(Finding("ambiguous", f"still moving at the step limit ({100 * min(moving):.2g}% over the "
                                 f"last {MOTION_STEPS} steps); raise --max-steps"))
        found.sort(key=lambda f: -LEVELS.index(f.level))  # stable: the checks' own order within a level
        worst = found[0] if found else None
        if worst is None:
            agree = f"{len(sel)} restart{'s' if len(sel) != 1 else ''} agree" if len(sel) > 1 else "one restart"
            if name in own_units:
                agree = "the best restart's reading"
            why = (f"the latent tells the frames apart (score {best_score:.2f})" if best_score is not None
                   else "the latent is a measured position or size, read linearly")
            out[name] = Verdict("trusted", f"{agree}; {why}")
        else:
            more = f" (and {len(found) - 1} more reason{'s' if len(found) > 2 else ''})" if len(found) > 1 else ""
            out[name] = Verdict(worst.level, worst.reason + more, tuple(f.reason for f in found[1:]))
    return out


def rejudge(result, analysis=None, calibrated: Iterable[str] = (), extra: Iterable[Finding] = ()) -> dict[str, Verdict]:
    """The verdicts of a FitResult again, after calibration (which can make a unit-dependent
    constant physical, or show a calibrated value outside the equation's bounds)."""
    findings = [Finding.from_dict(f) for f in result.checks.get("findings", [])] + list(extra)
    return judge(list(result.parameters), result.runs, result.selected, result.values, findings,
                 analysis=analysis, calibrated=calibrated, own_units=result.meta.get("own_units", ()))
