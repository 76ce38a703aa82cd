"""The checks of a latent against the video itself, from the best run (findings for every constant).

The loss alone cannot judge a fit (the harmonic trap, a latent that follows a start-up transient,
pixel noise fitted by an encoder with more weights than frames). These checks look at the video:
- the score of the best restart (fitode.train.score): does its latent tell the frames apart?
  (a learned latent only: the observation model says where it applies)
- the fit: the equation with the estimated constants must follow the latent in its windows;
- the periods: where the frames repeat, the latent and the equation's own solution (the rollout
  with the estimated constants) must repeat with them;
- activity: a learned latent must move wherever the frames still change, not only in a transient;
- one-way motion: a decay, a drain or a fall can be bent by a free encoder into a solution with
  other constants, which no score can see; only a linear readout of few components is trusted.
fitode.train.assess weighs their findings with the rest into the verdicts.
"""
from __future__ import annotations

import math

import numpy as np

from .findings import Finding
from .score import dominant_period, separation_score

SCORE_MIN = 0.5  # right latents scored 0.78-0.995 on every motion case tried, wrong ones -0.5 to 0.45
PERIOD_TOL = 0.1
MISS_MAX = 0.05  # window prediction error over the latent's variance: right fits measured 1e-5 to 1e-3
ONE_WAY_RHO = 0.95
ONE_WAY_RANK = 2  # a linear readout of more components than this can bend a one-way trajectory
CROSSINGS = 3  # a rollout crossing its mean this often oscillates over the clip (crossing_period)
QUIET = 0.1  # a quarter of the clip where the latent moves less than this fraction of its spread


def crossing_period(series: np.ndarray, dt: float) -> float | None:
    """The period (s) of a smooth series (T,) or (T, k; its first column) from its crossings of its
    mean: twice their mean spacing where it crosses at least CROSSINGS times (a rollout that
    oscillates over the clip does), else None. For a noiseless curve, where the spectrum of two
    cycles may not stand out of its low edge."""
    x = np.asarray(series, dtype=float)
    x = x if x.ndim == 1 else x[:, 0]
    x = x - float(np.mean(x))
    if len(x) < 8 or not np.all(np.isfinite(x)):
        return None
    i = np.flatnonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))
    if len(i) < CROSSINGS:
        return None
    at = i + x[i] / (x[i] - x[i + 1])  # each crossing between its two frames, linearly
    return float(2.0 * np.mean(np.diff(at)) * dt)


def video_checks(latent: np.ndarray, rollout: np.ndarray, coefs: np.ndarray, dt: float, score: float | None,
                 oscillator: bool, encoder: str = "mlp", rank: int = 0,
                 miss: float | None = None, observation=None) -> tuple[list[Finding], dict[str, float | None]]:
    """Findings that hold for every constant, from the best run's latent and rollout (training
    frames only), the frames' principal components, the encoder's architecture and the rank of
    the signal subspace it read, and the best run's window miss (RunRecord.miss); and the numbers
    behind them. observation: the model that read the frames (None: the paper's free encoder);
    it says which of the checks that depend on what the latent is apply (its `applies`)."""
    applies = observation.applies if observation is not None else (lambda check: check in ("score", "quiet", "periods"))
    findings: list[Finding] = []
    numbers: dict[str, float | None] = {"score": score}
    if applies("score") and (score is None or not math.isfinite(score) or score < SCORE_MIN):
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
    t_latent = dominant_period(latent, dt) if oscillator else None
    # a measured latent reads one part of what the frames show: its own period is the reference
    t_frames = (dominant_period(coefs, dt) if applies("periods") else t_latent) if oscillator else None
    finite_roll = rollout[np.all(np.isfinite(rollout), axis=1)] if rollout.size else rollout
    t_roll = dominant_period(finite_roll, dt) if oscillator and len(finite_roll) == len(rollout) else None
    if t_roll is None and t_latent is not None and len(finite_roll) == len(rollout):
        # the spectrum's test of a peak is borderline on two cycles: a generated 7-degree swing's
        # latent passed it and its own fitted rollout, the same curve to 0.5%, did not
        t_roll = crossing_period(finite_roll, dt)
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
    quiet = _quiet_quarter(latent, coefs, dt) if applies("quiet") else None
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
        # a latent that still tells that quarter's frames apart follows the motion there, only
        # smaller (a decaying oscillation near rest): it is not stuck
        if moves_z < QUIET and moves_f > 3 * QUIET and separation_score(latent[part], coefs[part], exclude=2) < SCORE_MIN:
            return (f"the latent stops moving after {q * n // 4 * dt:.3g} s while the frames still change: "
                    "it follows only a start-up transient")
    return None
