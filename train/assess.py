"""The assessment: every verdict decided in one place, once, after any calibration.

Training and the measurement's checks leave findings in result.checks (fitode.train.latent_checks'
checks, the trajectory checks of a measured path). Here they meet what can only be
judged with the whole run in view, each rule with one threshold:
- what the equation lets a video measure (fitode.eqparse.identify): a constant that enters only
  through a combination is not trustworthy; one whose value depends on the latent's units is
  not trustworthy until calibrated, unless the observation measures the state in its own units;
- agreement: the restarts an estimate comes from must agree within AGREE_TOL;
- rivals: a restart left out that tells the frames apart as well (score within SCORE_MARGIN) and
  fits its latent about as well (RIVAL_MISS) but ended elsewhere makes the estimate ambiguous
  (selection.rivals; the interval reaches the farthest of them);
- settling: an estimate whose restarts all stopped at the step limit is ambiguous, and says how
  far it still moved over its last MOTION_STEPS steps (a path fitted directly: whose solver did
  not settle, and how far it moved from the windows' fit to the whole path's; the fit of a
  calibrated path whose zero the calibration sets is judged on none of the restarts);
- an interrupted run is ambiguous: its estimates come from unfinished training;
- the interval (fitode.train.interval, made before the assessment): where none could be made, or
  where the equation fitted without the clip's last quarter misses it by more than HELD_OUT_MAX
  times the residuals there and more than it does on every path of the bootstrap (the one
  trajectory with the residuals resampled: residuals that hang together move a short fit's
  prediction by several times themselves where the equation holds), the equation does not explain the clip as well as the interval
  assumes: a doubt the interval cannot carry, so the estimate is ambiguous, each constant that the
  fit without the quarter moves out of its 95% interval (one it leaves inside is a note);
- precision: TRUSTED promises the number within PROMISE of the truth, 99 times in 100, so a
  constant whose 99% interval (the 95% one widened by Z99 / Z95) reaches further than PROMISE
  from its value is ambiguous: the clip pins it less well than the word promises (a fall of 30
  frames whose measured radius bends the path, g +8% with a 95% interval of +-7%, was trusted).
The worst finding decides: any "not trustworthy" beats "ambiguous", which beats "trusted". Every
finding's reason is shown once: as a verdict's reason, or among the warnings. The warnings say
nothing else that could make a number unreliable; notes (restarts left out, failed) say what
happened and why, naming the rule that applied.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Mapping

import numpy as np

from .findings import LEVELS, Finding, Verdict
from .selection import AGREE_TOL, rivals

MOTION_STEPS = 200
HELD_OUT_MAX = 3.0
PROMISE = 0.05  # TRUSTED: within 5% of the truth at 99% (the coverage bench's false trust: > 5% off)
Z99_OVER_Z95 = 2.5758 / 1.9600


@dataclass
class Assessment:
    """The verdict per constant, every finding behind them, and the lines shown under the table:
    warnings (findings that are no verdict's headline) and notes (what happened, no judgement)."""

    verdicts: dict[str, Verdict]
    findings: list[Finding]
    warnings: list[str]
    notes: list[str]

    def apply(self, result) -> None:
        """Record the assessment on its FitResult: verdicts, warnings, notes, and every finding
        under checks["assessed"] (checks["findings"] stay the measurement's, so that a result can
        be assessed again, after a calibration, from what training found)."""
        result.verdicts = {n: v.to_dict() for n, v in self.verdicts.items()}
        result.warnings, result.notes = list(self.warnings), list(self.notes)
        result.checks = {**result.checks, "assessed": [f.to_dict() for f in self.findings]}


def assess(result, analysis=None, *, calibrated: Iterable[str] = (), extra: Iterable[Finding] = ()) -> Assessment:
    """The assessment of a FitResult. analysis: the equation's IdentifiabilityReport (None: not
    judged on it); calibrated: the constants a calibration put in physical units; extra: the
    calibration's findings. result.meta["physical_units"]: the observation measured the state in
    its own units, so that no constant waits for a calibration."""
    calibrated = set(calibrated)
    physical_units = bool(result.meta.get("physical_units"))
    measured = list(_measurement_findings(result)) + list(extra)
    interrupted = bool(result.meta.get("interrupted"))
    missed = _held_out_missed(result.checks.get("interval"), result.parameters)
    if not interrupted:
        measured += _interval_findings(result, missed)
    if interrupted:
        measured.append(Finding("ambiguous", "training was interrupted (Ctrl-C): the estimates come from "
                                "unfinished training"))
    runs = {r.index: r for r in result.runs}
    selected = [runs[i] for i in result.selected]
    scores = [r.score for r in selected if r.score is not None and math.isfinite(r.score)]
    best_score = max(scores) if scores else None
    own_units = set(result.meta.get("own_units", ()))
    # one fit of the calibrated path (fitode.calibrate._fixes_zero): the restarts differ only in the
    # zero the calibration sets, so their agreement, rivals and settling say nothing of it
    refitted = set((result.calibration or {}).get("gauge_fixed") or ()) if calibrated else set()
    points_only = _points_only(result)
    verdicts: dict[str, Verdict] = {}
    everything: list[Finding] = list(measured)
    for name in result.parameters:
        value = result.parameters[name].value
        sources = [runs[result.best]] if name in own_units else selected
        found = [f for f in measured if f.names is None or name in f.names]
        mine = _identifiability(name, analysis, calibrated, physical_units, result)
        if name not in refitted:
            mine += _agreement(name, value, sources)
            mine += _rivals(name, result)
        mine += _precision(name, result.parameters[name], _shares(result, name), points_only)
        if not interrupted and name not in refitted:
            mine += _settling(name, sources, int(result.settings.get("max_steps", 0)), bool(result.meta.get("direct")))
        everything += mine
        found += mine
        found.sort(key=lambda f: -LEVELS.index(f.level))  # stable: the checks' own order within a level
        verdicts[name] = _verdict(found, sources, best_score, name in own_units, name in refitted)
    return Assessment(verdicts, everything, _warnings(everything, verdicts), _notes(result, missed))


def _measurement_findings(result) -> Iterable[Finding]:
    return (Finding.from_dict(f) for f in result.checks.get("findings", []))


def _interval_findings(result, missed) -> list[Finding]:
    """Does the equation explain the clip as well as the interval assumes? (see the module
    docstring; missed: _held_out_missed's answer). Nothing where no interval was asked for
    (checks without "interval")."""
    if "interval" not in result.checks:
        return []
    boot = result.checks["interval"]
    if boot is None:
        return [Finding("ambiguous", "no interval could be made: the path cannot be fitted as one trajectory of "
                        "the equation over the clip")]
    if missed is None or missed[1] == ():
        return []
    # (beyond what the same residuals, resampled about the one trajectory, reach where the equation holds)
    return [Finding("ambiguous", missed[0] + ": one set of constants does not predict the clip", missed[1])]


def _held_out_missed(boot, parameters) -> tuple[str, tuple[str, ...] | None, tuple[str, ...]] | None:
    """Where the equation fitted without the last quarter misses it (see the module docstring):
    what to say, the constants that fit moves out of their 95% interval (relative to the value:
    the fit is in the path's units, the interval in the reported ones; a constant without an
    interval counts as moved, and None is every constant, where the record has no such fit), and
    those it leaves inside it. A slow error
    of the reading (a tracked centre off by a tenth of a pixel, periodic with a released swing)
    mispredicts a quarter by 3.6 to 4 times the residuals and moves the length by 0.05%, its
    interval being 0.2% (the pivot's share): no doubt about that number. None where the quarter
    is predicted."""
    held, null = (boot or {}).get("held_out"), (boot or {}).get("held_out_null")
    if held is None or held <= max(HELD_OUT_MAX, null or 0.0):
        return None
    said = (f"the equation fitted without the clip's last quarter misses it by {held:.3g} times the residuals of "
            "the whole clip's fit there" + (f" (its residuals resampled reach {null:.3g})" if null else ""))
    without, values = boot.get("held_out_values") or {}, boot.get("trajectory") or {}
    if not without:
        return said, None, ()

    def inside(name: str) -> bool:
        est = parameters.get(name)
        iv = getattr(est, "interval", None)  # (low, high) about the reported value
        if not iv or not all(math.isfinite(v) for v in iv) or not values.get(name) or not est.value:
            return False
        return abs(without[name] / values[name] - 1.0) <= (iv[1] - iv[0]) / 2 / abs(est.value)
    moved = tuple(n for n in without if not inside(n))
    return said, moved, tuple(n for n in without if n not in moved)


def _precision(name: str, est, shares: Mapping[str, float] | None = None, points: bool = False) -> list[Finding]:
    """The 99% interval reaches further than PROMISE from the value (see the module docstring).
    shares: the interval's own shares (as normal standard deviations, fitode.train.interval.combine):
    where one of them carries most of its width, the reason names it and what narrows it, since a
    short ruler, not the clip, is then what a user can mend. points: the calibration share is the
    --calibrate points' alone (no scale stick), so the reason names them, not a ruler."""
    iv = getattr(est, "interval", None)
    if not iv or not all(math.isfinite(v) for v in iv):
        return []
    reach = max(est.value - iv[0], iv[1] - est.value) * Z99_OVER_Z95 / max(abs(est.value), 1e-300)
    if reach <= PROMISE:
        return []
    cause = _dominant(shares or {})
    said = ""
    if cause in SHARE_CAUSES:
        width = _widths(shares)[cause] / max(abs(est.value), 1e-300)
        said = f"; most of it (+-{_pct(width)}) is {POINTS_CAUSE if points and cause == 'calibration' else SHARE_CAUSES[cause]}"
    return [Finding("ambiguous", f"the clip pins it only to +-{_pct(reach / Z99_OVER_Z95)} (95%), "
                    f"+-{_pct(reach)} at 99%: more than the {PROMISE:.0%} a trusted number promises" + said, (name,))]


# what carries most of an interval (interval.combine's shares), and what narrows it
SHARE_CAUSES = {
    "calibration": "the scale given: a longer ruler in view, or its ends' precision written as "
                   "--scale X1,Y1,X2,Y2±P=D, narrows it (or --calibrate's values, where they set the scale)",
    "residuals": "the measured path's scatter about the equation's trajectory: a longer clip, or a higher "
                 "frame rate, narrows it",
    "timing": "the frame rate's uncertainty: --fps with the camera's true rate narrows it",
}
# the calibration share where --calibrate alone set the scale (a drain calibrated at its first and last
# frame: +-4.3% of k, the level's reading error at those two frames carried through the map; five points
# spread over a generated drain gave +-2.8% where its two ends gave +-3.4%)
POINTS_CAUSE = ("the path's reading at the --calibrate points: a reading error there moves the map and with it "
                "the constant; more points, spread over the clip, narrow it")
DOMINANT = 0.5  # the share of the interval's variance one cause must carry to be named


def _widths(shares: Mapping[str, float]) -> dict[str, float]:
    """Each share's reach into the 95% half width: gap and rivals as they are, the others as
    standard deviations (interval.combine)."""
    from statistics import NormalDist
    z = NormalDist().inv_cdf(0.975)
    return {k: abs(float(v)) * (1.0 if k in ("gap", "rivals") else z) for k, v in shares.items()
            if isinstance(v, (int, float)) and math.isfinite(v)}


def _points_only(result) -> bool:
    """Whether --calibrate's points alone set the scale: a calibration applied and no scale stick."""
    stick = float((result.meta.get("length") or {}).get("relative_std") or 0.0)
    return result.calibration is not None and not stick


def _dominant(shares: Mapping[str, float]) -> str | None:
    """The share that carries more than DOMINANT of the interval's variance, if one does."""
    widths = _widths(shares)
    total = sum(w * w for w in widths.values())
    if total <= 0:
        return None
    name, width = max(widths.items(), key=lambda kv: kv[1])
    return name if width * width > DOMINANT * total else None


def _shares(result, name: str) -> Mapping[str, float]:
    """The shares of name's interval as the interval stage recorded them (checks["interval"])."""
    shares = ((result.checks or {}).get("interval") or {}).get("shares") or {}
    return shares.get(name) or {}


def _pct(x: float) -> str:
    return f"{100 * x:.2g}%" if x < 10 else "more than 1000%"


def _identifiability(name: str, analysis, calibrated: set[str], physical_units: bool, result) -> list[Finding]:
    if analysis is None:
        return []
    c = analysis[name]
    if not c.separable:
        what = f"only {c.combination}" if c.combination else "no value for it alone"
        return [Finding("not trustworthy", f"the equation lets a video measure {what}", (name,))]
    if name in calibrated or physical_units:
        return []
    if c.scale == "dependent":
        # only a learned latent has arbitrary units: a measured path is in px, m or radians
        return [Finding("not trustworthy", "its value depends on the free encoder's arbitrary units; measure the "
                        "state (--observe position, level, size) or give --calibrate with known values of it",
                        (name,))]
    if c.scale == "free-small-amplitude" and not _gauge_scaled(result):
        return [Finding("ambiguous", "scale-free only for small amplitudes: with large swings the latent's "
                        "arbitrary scale biases it; calibrate the state to be sure", (name,))]
    return []


def _agreement(name: str, value: float, sources) -> list[Finding]:
    vals = [r.value(name) for r in sources if name in r.final]
    if len(vals) > 1 and np.std(vals) > AGREE_TOL * max(abs(value), 1e-12):
        return [Finding("ambiguous", f"the restarts it comes from disagree by more than {AGREE_TOL:.0%}: "
                        + ", ".join(f"{v:.4g}" for v in vals), (name,))]
    return []


def _rivals(name: str, result) -> list[Finding]:
    """Restarts left out that tell the frames apart as well and fit their latent about as well
    (selection.rivals); the interval spans them (fitode.train.interval)."""
    found = rivals(result, name, AGREE_TOL)
    if not found:
        return []
    return [Finding("ambiguous", "restarts that tell the frames apart as well ended elsewhere: "
                    + "; ".join(f"run {r.index + 1} at {_shown(r, name)} (score {r.score:.2f}, loss {r.loss:.3g})"
                                for r in found), (name,))]


def _shown(run, name: str) -> str:
    """A run's value as the run table prints it, and as compared where its latent runs the other way."""
    final, aligned = run.final[name], run.value(name)
    return f"{final:.4g}" if aligned == final else f"{final:.4g} ({aligned:.4g} with its latent turned round)"


def _settling(name: str, sources, max_steps: int, direct: bool = False) -> list[Finding]:
    """No restart the estimate comes from settled: it stopped at the step limit, still moving.
    direct: the measured path was fitted directly (train/direct.py), whose solver has iterations
    of its own that --max-steps does not set: its restarts' two steps are the windows' fit and the
    whole path's, and that says so."""
    if not sources or any(r.converged for r in sources):
        return []
    if direct:  # its history: the start, the windows' fit, the whole path's fit
        moved = [abs(h[-1] - h[-2]) / max(abs(h[-1]), 1e-12) for h in (r.history.constants.get(name, []) for r in sources)
                 if len(h) >= 3]
        how = f" (it moved {100 * min(moved):.2g}% from the windows' fit to the whole path's)" if moved else ""
        return [Finding("ambiguous", "no restart's fit of the measured path settled within its solver's iterations"
                        + how + ": the path may hold it only loosely", (name,))]
    moved = [m for m in (_motion(r, name) for r in sources) if m is not None]
    how = f"; it moved {100 * min(moved):.2g}% over the last {MOTION_STEPS} steps" if moved else ""
    return [Finding("ambiguous", f"no restart it comes from settled before the step limit ({max_steps} steps){how}; "
                    "raise --max-steps", (name,))]


def _motion(run, name: str) -> float | None:
    """Relative change of a constant over the last MOTION_STEPS steps of a run's history."""
    series = run.history.constants.get(name, [])
    if len(series) < 2:
        return None
    now, then = series[-1], series[-1 - min(MOTION_STEPS, len(series) - 1)]  # a short run: since its start
    return abs(now - then) / max(abs(now), 1e-12)


def _gauge_scaled(result) -> bool:
    """True when the best run learned the scale between latent and state (fitode.eqparse.gauge),
    so a large swing no longer biases an amplitude-dependent constant."""
    gauge = next((r.gauge for r in result.runs if r.index == result.best), {})
    return any(abs(g.get("scale", 1.0) - 1.0) > 1e-9 for g in gauge.values())


def _verdict(found: list[Finding], sources, best_score: float | None, own_units: bool,
             refitted: bool = False) -> Verdict:
    if found:
        more = f" (and {len(found) - 1} more reason{'s' if len(found) > 2 else ''})" if len(found) > 1 else ""
        return Verdict(found[0].level, found[0].reason + more, tuple(f.reason for f in found[1:]))
    agree = f"{len(sources)} restarts agree" if len(sources) > 1 else "one restart"
    if own_units:
        agree = "the best restart's reading"
    if refitted:
        agree = "one fit of the path as calibrated, whose zero the calibration sets"
    why = (f"the latent tells the frames apart (score {best_score:.2f})" if best_score is not None
           else "the latent is a measured quantity, read linearly")
    return Verdict("trusted", f"{agree}; {why}")


def _warnings(findings: list[Finding], verdicts: Mapping[str, Verdict]) -> list[str]:
    """Every finding not already a verdict's headline reason, once."""
    shown = {v.reason.split(" (and ")[0] for v in verdicts.values()}
    out: list[str] = []
    for f in findings:
        names = [n for n in (f.names or verdicts) if n in verdicts]
        line = (f"{', '.join(names)}: " if f.names is not None else "") + f.reason
        if f.reason not in shown and line not in out and f.level != "trusted":
            out.append(line)
    return out


def _notes(result, missed) -> list[str]:
    n_runs = len(result.runs)
    failed = [r.index for r in result.runs if r.status == "failed"]
    out = []
    if missed is not None and missed[2]:
        stay = missed[2]
        out.append(f"{missed[0]}, yet {', '.join(stay)} fitted without it stay{'s' if len(stay) == 1 else ''} inside "
                   "the 95% interval: a slow error of the reading, which the interval carries")
    if failed:
        out.append(f"{len(failed)} of {n_runs} restarts failed (runs {', '.join(str(i + 1) for i in failed)})")
    left = {int(i): why for i, why in result.meta.get("left_out", {}).items() if int(i) not in failed}
    if left:
        out.append(f"{len(left)} of {n_runs} restarts left out of the estimate: "
                   + "; ".join(f"run {i + 1}, {why}" for i, why in sorted(left.items())))
    return out

