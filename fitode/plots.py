"""The run's figures (matplotlib, Agg backend: no display needed).

Each function takes plain data (arrays, lists of run dicts as in result.json / fit.json), so the
same code draws a finished run, a partial one, or a FitResult loaded back from fit.json.
A run dict has index, status ("ok", "failed", "interrupted", ...), optionally selected, and
history {step, loss, constants{name: [...]}}.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

DPI = 110


def _plt():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def _colours(n: int) -> list:
    plt = _plt()
    cmap = plt.get_cmap("tab10" if n <= 10 else "tab20")
    return [cmap(i % cmap.N) for i in range(max(n, 1))]


def plot_latent(path: str | Path, time: Sequence[float], latent: np.ndarray, rollout: np.ndarray,
                train_frames: int, states: Sequence[str], *, window: int | None = None,
                ylabels: Sequence[str] | None = None) -> Path:
    """Encoded latent (dots) and the physics rollout from the first frames (line), per state.

    The rollout starts from the first frames only and runs over the whole clip, so everything
    after the first window is a prediction; frames beyond train_frames were not trained on and are
    shaded as extrapolation.

    ylabels: one axis label per state, for a calibrated latent (its values in physical units);
    None labels every axis in latent units (see `latent_label`).
    """
    plt = _plt()
    t = np.asarray(time, dtype=float)
    z = np.asarray(latent, dtype=float).reshape(len(t), -1)
    r = np.asarray(rollout, dtype=float).reshape(len(t), -1)
    d = z.shape[1]
    fig, axes = plt.subplots(d, 1, figsize=(9, 2.6 * d + 0.6), sharex=True, squeeze=False)
    t_train = t[train_frames] if train_frames < len(t) else None
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(t, z[:, i], ".", ms=3.5, color="tab:blue", label="encoded frames")
        finite = np.isfinite(r[:, i])
        ax.plot(t[finite], r[finite, i], "-", lw=1.4, color="tab:orange", label="physics rollout from the first frames")
        lo, hi = _limits(z[:, i], r[finite, i])
        ax.set_ylim(lo, hi)  # a diverging rollout must not squash the data
        if t_train is not None:
            ax.axvspan(t_train, t[-1], color="0.85", zorder=0, label="extrapolated (not trained on)")
            ax.axvline(t_train, color="0.4", lw=0.8, ls="--")
        if window and window < len(t):
            ax.axvline(t[window - 1], color="tab:green", lw=0.8, ls=":",
                       label=f"end of the first {window}-frame window: the rollout after it is a prediction")
        ax.set_ylabel(ylabels[i] if ylabels else latent_label(states[i]))
        ax.grid(alpha=0.3)
        if not finite.all():
            ax.text(0.99, 0.03, "rollout left the finite range", transform=ax.transAxes, ha="right",
                    va="bottom", fontsize=8, color="tab:red")
    # above the axes: inside, a legend hides the very points it explains
    axes[0, 0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize=8, frameon=False)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("encoded latent and physics rollout", fontsize=11)
    return _save(fig, path)


def latent_label(state: str) -> str:
    """Axis label of an uncalibrated state. Its scale is whatever the encoder learned (values of
    +-40 are common), so it must not read as radians or metres."""
    return f"{state}\nlatent units (not calibrated)"


def _limits(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    a = a[np.isfinite(a)]
    if a.size == 0:
        return -1.0, 1.0
    lo, hi = float(a.min()), float(a.max())
    if b.size:  # show the rollout too, but only up to twice the data's range
        span = hi - lo or 1.0
        lo = max(min(lo, float(np.nanmin(b))), lo - span)
        hi = min(max(hi, float(np.nanmax(b))), hi + span)
    pad = 0.06 * ((hi - lo) or 1.0)
    return lo - pad, hi + pad


def plot_params(path: str | Path, runs: Sequence[Mapping[str, Any]], estimates: Mapping[str, float],
                *, units: Mapping[str, str | None] | None = None, truth: Mapping[str, float] | None = None) -> Path:
    """Each constant's trajectory over training for every restart (log-scaled steps), the paper's
    robustness figure: the estimate as a black line, failed runs dashed and ended with a red x,
    runs left out of the estimate drawn faint."""
    plt = _plt()
    names = _constant_names(runs) or list(estimates)
    n = max(len(names), 1)
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.7 * n + 0.6), sharex=True, squeeze=False)
    colours = _colours(len(runs))
    for ax, name in zip(axes[:, 0], names):
        for run, c in zip(runs, colours):
            steps, vals = _series(run, name)
            if steps.size == 0:
                continue
            failed = run.get("status") not in ("ok", "ended", "running", "interrupted")
            faint = run.get("selected") is False and not failed
            ax.plot(steps, vals, "--" if failed else "-", color=c, lw=1.2, alpha=0.35 if faint else 0.95,
                    label=f"run {run.get('index', 0) + 1} (init {_fmt(_init(run, name, vals))})" + (" failed" if failed else ""))
            if failed:
                ax.plot(steps[-1], vals[-1], "x", color="tab:red", ms=8, mew=2)
        if name in estimates and estimates[name] is not None and math.isfinite(estimates[name]):
            ax.axhline(estimates[name], color="k", lw=1.3, label=f"estimate {_fmt(estimates[name])}")
        if truth and name in truth:
            ax.axhline(truth[name], color="k", lw=1, ls=":", label=f"truth {_fmt(truth[name])}")
        unit = (units or {}).get(name)
        ax.set_ylabel(f"{name}" + (f" [{unit}]" if unit else ""))
        ax.set_xscale("log")
        _robust_ylim(ax, runs, name, estimates.get(name))
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="best", ncol=2, framealpha=0.85)
    axes[-1, 0].set_xlabel("training step")
    axes[0, 0].set_title("constants during training, every restart")
    return _save(fig, path)


def _robust_ylim(ax, runs, name: str, estimate: float | None) -> None:
    """Keep a wild early excursion of one run from flattening every other curve."""
    ends = []
    allv = []
    for run in runs:
        _, v = _series(run, name)
        v = v[np.isfinite(v)]
        if v.size:
            ends.append(v[-1])
            allv.append(v)
    if not allv:
        return
    allv = np.concatenate(allv)
    lo, hi = np.percentile(allv, [1, 99])
    lo, hi = min(lo, *ends), max(hi, *ends)
    if estimate is not None and math.isfinite(estimate):
        lo, hi = min(lo, estimate), max(hi, estimate)
    pad = 0.08 * ((hi - lo) or max(abs(hi), 1.0))
    ax.set_ylim(lo - pad, hi + pad)


def plot_loss(path: str | Path, runs: Sequence[Mapping[str, Any]]) -> Path:
    """Training loss of every restart against step (log y, log x)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 3.6))
    for run, c in zip(runs, _colours(len(runs))):
        h = run.get("history") or {}
        steps = np.asarray(h.get("step", []), dtype=float)
        loss = np.asarray([np.nan if v is None else v for v in h.get("loss", [])], dtype=float)
        ok = np.isfinite(loss) & (loss > 0)
        if not ok.any():
            continue
        failed = run.get("status") not in ("ok", "ended", "running", "interrupted")
        ax.plot(steps[ok], loss[ok], "--" if failed else "-", color=c, lw=1.1,
                label=f"run {run.get('index', 0) + 1}" + (" (failed)" if failed else "")
                + (" (best)" if run.get("best") else ""))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("training step")
    ax.set_ylabel("loss (MSE + KL)")
    ax.grid(alpha=0.3, which="both")
    if ax.lines:
        ax.legend(fontsize=8, ncol=2)
    ax.set_title("training loss, every restart")
    return _save(fig, path)


def plot_frames(path: str | Path, frames, dt: float, n: int = 8, t0: float = 0.0) -> Path:
    """A strip of n frames evenly spread over the clip, after preprocessing, with their times."""
    plt = _plt()
    x = np.asarray(frames.detach().cpu() if hasattr(frames, "detach") else frames, dtype=np.float32)
    if x.ndim == 3:
        x = x[:, None]
    total = x.shape[0]
    idx = np.unique(np.linspace(0, total - 1, min(n, total)).round().astype(int))
    h, w = x.shape[2], x.shape[3]
    per = min(1.6 * max(w / h, 0.5), 14.0 / len(idx))  # inches per frame; the strip stays under ~14 in
    fig, axes = plt.subplots(1, len(idx), figsize=(per * len(idx), max(per * h / w, 1.0) + 0.7), squeeze=False)
    lo, hi = float(x.min()), float(x.max())
    for ax, i in zip(axes[0], idx):
        img = x[i]
        if img.shape[0] == 3:
            ax.imshow(np.clip(img.transpose(1, 2, 0), 0, 1))
        else:
            ax.imshow(img[0], cmap="gray", vmin=lo, vmax=hi if hi > lo else lo + 1)
        ax.set_title(f"t={t0 + i * dt:.2f}s", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"preprocessed frames ({total} frames of {w}x{h} pixels (WxH), dt {dt:.4g} s)", fontsize=9)
    return _save(fig, path)


def _constant_names(runs) -> list[str]:
    for run in runs:
        c = (run.get("history") or {}).get("constants")
        if c:
            return list(c)
    return []


def _series(run: Mapping[str, Any], name: str) -> tuple[np.ndarray, np.ndarray]:
    h = run.get("history") or {}
    steps = np.asarray(h.get("step", []), dtype=float)
    vals = np.asarray([np.nan if v is None else v for v in (h.get("constants") or {}).get(name, [])], dtype=float)
    m = min(len(steps), len(vals))
    return steps[:m], vals[:m]


def _init(run: Mapping[str, Any], name: str, v: np.ndarray) -> float:
    init = (run.get("init") or {}).get(name)
    if init is not None:
        return float(init)
    return float(v[0]) if v.size else math.nan


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _save(fig, path: str | Path) -> Path:
    plt = _plt()
    path = Path(path)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path
