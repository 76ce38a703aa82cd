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


def _figure(pyplot: bool = False, **kw):
    """A matplotlib Figure whose layout engine (constrained) runs as it is saved, with no call of
    its own. The files are drawn without pyplot: its import and figure manager cost about a third
    of a second a run and no window is shown; pyplot: a figure pyplot manages, for a user's session
    (Result.plot), where plt.show() shows it."""
    if pyplot:
        import matplotlib.pyplot as plt
        return plt.figure(layout="constrained", **kw)
    from matplotlib.figure import Figure
    return Figure(layout="constrained", **kw)


def _colours(n: int) -> list:
    from matplotlib import colormaps
    cmap = colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(i % cmap.N) for i in range(max(n, 1))]


def plot_latent(path: str | Path, time: Sequence[float], latent: np.ndarray, rollout: np.ndarray,
                train_frames: int, states: Sequence[str], *, window: int | None = None,
                ylabels: Sequence[str] | None = None, angles: Sequence[str] = (), measured: bool = False) -> Path:
    """latent.png: latent_figure saved at path."""
    return _save(latent_figure(time, latent, rollout, train_frames, states, window=window, ylabels=ylabels,
                               angles=angles, measured=measured), path)


def latent_figure(time: Sequence[float], latent: np.ndarray, rollout: np.ndarray, train_frames: int,
                  states: Sequence[str], *, window: int | None = None, ylabels: Sequence[str] | None = None,
                  angles: Sequence[str] = (), measured: bool = False, pyplot: bool = False):
    """Encoded latent (dots) and the physics rollout from the first frames (line), per state: a Figure.
    measured: the dots are a measured path fitted directly by one trajectory (train/direct.py), so
    no training window applies and the line is that trajectory.

    The rollout starts from the first frames only and runs over the whole clip, so everything
    after the first window is a prediction; frames beyond train_frames were not trained on and are
    shaded as extrapolation.

    ylabels: one axis label per state, for a calibrated latent (its values in physical units);
    None labels every axis in latent units (see `latent_label`). angles: the states that are an
    angle in radians, which get a second axis in degrees. pyplot: a figure pyplot manages (_figure).
    """
    t = np.asarray(time, dtype=float)
    z = np.asarray(latent, dtype=float).reshape(len(t), -1)
    r = np.asarray(rollout, dtype=float).reshape(len(t), -1)
    d = z.shape[1]
    fig = _figure(pyplot, figsize=(9, 2.6 * d + 0.6))
    axes = fig.subplots(d, 1, sharex=True, squeeze=False)
    t_train = t[train_frames] if train_frames < len(t) else None
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(t, z[:, i], ".", ms=3.5, color="tab:blue", label="measured frames" if measured else "encoded frames")
        finite = np.isfinite(r[:, i])
        ax.plot(t[finite], r[finite, i], "-", lw=1.4, color="tab:orange",
                label="the equation's trajectory fitted to them" if measured else "physics rollout from the first frames")
        lo, hi = _limits(z[:, i], r[finite, i])
        ax.set_ylim(lo, hi)  # a diverging rollout must not squash the data
        if t_train is not None:
            ax.axvspan(t_train, t[-1], color="0.85", zorder=0, label="extrapolated (not trained on)")
            ax.axvline(t_train, color="0.4", lw=0.8, ls="--")
        if window and window < len(t) and not measured:
            ax.axvline(t[window - 1], color="tab:green", lw=0.8, ls=":",
                       label=f"end of the first {window}-frame window: the rollout after it is a prediction")
        ax.set_ylabel(ylabels[i] if ylabels else latent_label(states[i]), fontsize=9)
        if states[i] in angles:
            ax.secondary_yaxis("right", functions=(np.degrees, np.radians)).set_ylabel("degrees")
        ax.grid(alpha=0.3)
        if not finite.all():
            ax.text(0.99, 0.03, "rollout left the finite range", transform=ax.transAxes, ha="right",
                    va="bottom", fontsize=8, color="tab:red")
    # above the axes: inside, a legend hides the very points it explains
    axes[0, 0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize=8, frameon=False)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("the measured path and the equation's trajectory" if measured else "encoded latent and physics rollout",
                 fontsize=11)
    return fig


def latent_label(state: str) -> str:
    """Axis label of an uncalibrated state. Its scale is whatever the encoder learned (values of
    +-40 are common), so it must not read as radians or metres."""
    return f"{state}\nlatent units (not calibrated)"


READING_WORDS = {"line": "the position along the line", "radius": "the apparent radius",
                 "1/radius": "1 / the apparent radius"}


def state_labels(result) -> list[str]:
    """The axis label of each state of a FitResult's latent (uncalibrated): its own units where the
    observation measured it in them (radians for an angle), else latent units, saying what the
    latent is affine in where a measured model read it."""
    m = result.meta.get("measurement") or {}
    readings = m.get("states") or {}
    out = []
    units = result.meta.get("units") or {}
    for s in result.states:
        how = readings.get(s)
        if units.get(s):
            out.append(f"{s} ({units[s]}, {'up' if how == 'y' else 'measured'})")
        elif result.meta.get("physical_units"):
            out.append(f"{s} (radians)" if how == "angle" else f"{s}\nmeasured, in its own units")
        elif result.meta.get("measured") and how:
            what = READING_WORDS.get(how, f"the {how}")
            out.append(f"{s}: latent units\n(not calibrated), affine in\n{what}")
        else:
            out.append(latent_label(s))
    return out


def angle_states(result) -> list[str]:
    """The states of a FitResult that are an angle in radians (an angle observation's)."""
    readings = (result.meta.get("measurement") or {}).get("states") or {}
    return [s for s in result.states if readings.get(s) == "angle" and result.meta.get("physical_units")]


def params_view(result, parameters: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """plot_params' keywords for a FitResult and result.json's "parameters": every curve in the
    units of its estimate (a calibrated constant's history, learned in latent units, times the
    calibration's conversion), the runs each estimate comes from, and labels that say the units."""
    converted = ((result.calibration or {}).get("constants") or {})
    factors, labels, in_estimate, own = {}, {}, {}, []
    for name, p in parameters.items():
        c = converted.get(name) or {}
        if c.get("converted") and c.get("before"):
            factors[name] = float(c["after"]) / float(c["before"])
        unit = f" [{p['unit']}]" if p.get("unit") else ""
        if p.get("calibrated"):
            labels[name] = f"{name}{unit}\ncalibrated (curves converted)"
        elif p.get("latent_units"):
            labels[name] = f"{name}\nlatent units (not calibrated)"
        else:
            labels[name] = f"{name}{unit}"
        if p.get("best_run_only"):
            in_estimate[name], own = [int(result.best)], own + [name]
        else:
            in_estimate[name] = [int(i) for i in result.selected]
    return {"factors": factors, "labels": labels, "in_estimate": in_estimate, "own_units": own}


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
                *, units: Mapping[str, str | None] | None = None, truth: Mapping[str, float] | None = None,
                factors: Mapping[str, float] | None = None, in_estimate: Mapping[str, Sequence[int]] | None = None,
                labels: Mapping[str, str] | None = None, own_units: Sequence[str] = ()) -> Path:
    """Each constant's trajectory over training for every restart (log-scaled steps), the paper's
    robustness figure: the estimate as a black line, the restarts it comes from drawn bold and ended
    with a dot, the others faint, failed runs dashed and ended with a red x.

    factors: what each constant's history is multiplied by to be in the estimate's units (a
    calibration's conversion: the histories are in the latent's units); in_estimate: per constant,
    the run indices the estimate comes from (default: the runs marked selected); labels: a full
    y-axis label per constant (default: name [unit]); own_units: constants whose restarts each read
    the measured path in units of their own, so that only the estimate's runs are in its units: the
    others stay faint and out of the y range, and the panel says so."""
    names = _constant_names(runs) or list(estimates)
    n = max(len(names), 1)
    fig = _figure(figsize=(8, 2.9 * n + 0.6))
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)
    colours = _colours(len(runs))
    for ax, name in zip(axes[:, 0], names):
        factor = (factors or {}).get(name, 1.0)
        chosen = None if in_estimate is None or name not in in_estimate else set(in_estimate[name])
        for run, c in zip(runs, colours):
            steps, vals = _series(run, name)
            if steps.size == 0:
                continue
            vals = vals * factor
            failed = run.get("status") not in ("ok", "ended", "running", "interrupted")
            used = run.get("selected") is not False if chosen is None else run.get("index", 0) in chosen
            faint = not used and not failed
            ax.plot(steps, vals, "--" if failed else "-", color=c, lw=1.8 if used and not failed else 1.0,
                    alpha=0.3 if faint else 0.95,
                    label=f"run {run.get('index', 0) + 1} (init {_fmt(_init(run, name, vals) * factor)})"
                    + (" failed" if failed else " in the estimate" if used and chosen is not None else ""))
            if failed:
                ax.plot(steps[-1], vals[-1], "x", color="tab:red", ms=8, mew=2)
            elif used and chosen is not None:
                ax.plot(steps[-1], vals[-1], "o", color=c, ms=6, mec="k", mew=0.8)
        if name in estimates and estimates[name] is not None and math.isfinite(estimates[name]):
            ax.axhline(estimates[name], color="k", lw=1.3, label=f"estimate {_fmt(estimates[name])}")
        if truth and name in truth:
            ax.axhline(truth[name], color="k", lw=1, ls=":", label=f"truth {_fmt(truth[name])}")
        unit = (units or {}).get(name)
        ax.set_ylabel((labels or {}).get(name) or f"{name}" + (f" [{unit}]" if unit else ""), fontsize=9)
        ax.set_xscale("log")
        _robust_ylim(ax, runs, name, estimates.get(name), factor, chosen if name in own_units else None)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="best", ncol=2, framealpha=0.85)
        if name in own_units:
            ax.set_title(_wrap(f"each restart reads the measured path in units of its own, so {name} differs between "
                               "them by that alone: the estimate is the bold run's; the faint ones are in other units",
                               110), fontsize=7, loc="left")
    axes[-1, 0].set_xlabel("training step")
    fig.suptitle("constants during training, every restart", fontsize=11)
    return _save(fig, path)


def _robust_ylim(ax, runs, name: str, estimate: float | None, factor: float = 1.0,
                 chosen: set | None = None) -> None:
    """Keep a wild early excursion of one run from flattening every other curve; where the
    estimate comes from some runs only, the others may leave the view (they are in other units)."""
    ends = []
    allv = []
    for run in runs:
        if chosen is not None and run.get("index", 0) not in chosen:
            continue
        _, v = _series(run, name)
        v = v[np.isfinite(v)] * factor
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
    fig = _figure(figsize=(8, 3.6))
    ax = fig.subplots()
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
    """A strip of n frames evenly spread over the clip, after preprocessing, with their times: one
    image of the frames side by side (one axes lays out and draws in about two thirds of the time
    of one axes per frame)."""
    x = np.asarray(frames.detach().cpu() if hasattr(frames, "detach") else frames, dtype=np.float32)
    if x.ndim == 3:
        x = x[:, None]
    total = x.shape[0]
    idx = np.unique(np.linspace(0, total - 1, min(n, total)).round().astype(int))
    h, w = x.shape[2], x.shape[3]
    gap = max(2, w // 12)  # blank columns between frames
    colour = x.shape[1] == 3
    lo, hi = float(x.min()), float(x.max())
    tiles = [np.clip(x[i].transpose(1, 2, 0), 0, 1) if colour else x[i][0] for i in idx]
    blank = np.full((h, gap, 3) if colour else (h, gap), np.nan, dtype=np.float32)
    strip = np.concatenate([part for tile in tiles for part in (tile, blank)][:-1], axis=1)
    per = min(1.6 * max(w / h, 0.5), 14.0 / len(idx))  # inches per frame; the strip stays under ~14 in
    wide = per * len(idx)
    fig = _figure(figsize=(wide, max(wide * h / strip.shape[1], 0.3) + 0.7))  # the strip's own height, titles above
    ax = fig.subplots()
    if colour:  # the gaps white, as the page
        ax.imshow(np.where(np.isnan(strip), 1.0, strip))
    else:
        ax.imshow(np.ma.masked_invalid(strip), cmap="gray", vmin=lo, vmax=hi if hi > lo else lo + 1)
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle
    ax.add_collection(PatchCollection([Rectangle((k * (w + gap) - 0.5, -0.5), w, h) for k in range(len(idx))],
                                      facecolor="none", edgecolor="black", linewidth=0.8))
    for k, i in enumerate(idx):
        ax.text(k * (w + gap) + (w - 1) / 2, -1, f"t={t0 + i * dt:.2f}s", ha="center", va="bottom", fontsize=8)
    ax.set_xlim(-1.0, strip.shape[1])  # the borders inside the axes
    ax.set_ylim(h, -1.0)
    ax.set_axis_off()
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
    path = Path(path)
    fig.savefig(path, dpi=DPI)
    return path


# ---------------------------------------------------------------------------------------------
# track.png: what was measured, drawn on the frames

REGION_LABEL = {"any": "where the frames change", "brightness": "where the light changes most"}
NO_PLACE = {
    "any": "a free latent: the encoder learns its own reading of the whole frame, so there is no point, line "
           "or angle to draw here (latent.png shows the latent over time). The yellow box: where the frames change.",
    "brightness": "brightness: the light of the frames, decoded to linear light, read as a whole; the yellow box "
                  "holds the pixels whose light changes most. Its value over time is in latent.png.",
}


def plot_track(path: str | Path, measurement: Mapping[str, Any] | None, stills: Mapping[int, tuple[np.ndarray, Sequence[float]]],
               time: Sequence[float], *, readings: Sequence[Any] = (), stretch: Mapping[str, Any] | None = None,
               train_frames: int | None = None, calibrated: Mapping[str, tuple[float, float]] | None = None,
               source_frames: Sequence[int] | None = None, pieces: Mapping[str, Any] | None = None) -> Path:
    """Sample frames with what was measured drawn on them, and each measured reading over time.

    measurement: the record of result.json's "measurement" (source pixels); stills: {frame of the
    clip: (RGB image, imshow extent [left, right, bottom, top] in source pixels)}; time: (T,) the
    time of every frame of the clip; readings: fitode.measurement.readings (measured and fitted
    reading per state); stretch: the stretch record (frames of the clip, end exclusive), shaded;
    calibrated: {state: (A, B)}, the calibration's state = A * latent + B, for a second axis in the
    calibrated units where a reading is affine in the latent. source_frames: (T,) the source
    video's index of every frame of the clip, as track.csv's `frame` numbers them (None: the
    clip's own index). pieces: the pieces record (meta["pieces"], fitode.train.pieces: frames of
    the clip), each piece shaded and each event marked.
    """
    m = dict(measurement or {})
    t = np.asarray(time, dtype=float)
    idx = sorted(stills)
    track = _xy(m.get("track"), len(t))
    mended = [i for i in m.get("mended") or [] if 0 <= i < len(t)]
    strays = track[mended].copy()
    track[mended] = np.nan  # drawn apart: their centroid was something else, and the path was read from neighbours
    fitted = next((r.points for r in readings if r.points is not None), None)
    n_rows = 1 + len(readings)
    view = _view(m, track, fitted, stills)
    box = view or (lambda e: (e[0], e[3], e[1], e[2]))(next(iter(stills.values()))[1] if stills else (0, 1, 1, 0))
    aspect = (box[3] - box[1]) / max(box[2] - box[0], 1e-9)
    cols = max(len(idx), 1)
    per = 3.6 if cols <= 3 else 3.0  # inches per frame: a tall, narrow view (a fall) gets narrow columns
    per = min(max(6.0 / aspect, 1.2), per)
    width = max(per * cols, 8.5)
    tall = min(max((width / cols - 0.7) * aspect, 1.5), 6.0)  # what the frame's shape leaves of its column
    fig = _figure(figsize=(width, tall + 2.3 + 2.3 * len(readings)))
    # a row of its own for the legend of the frames: above them it would cover the title
    grid = fig.add_gridspec(n_rows + 1, max(len(idx), 1), height_ratios=[0.45, tall + 0.6] + [2.0] * len(readings))
    inside = _in_stretch(stretch, len(t), pieces)
    for k, i in enumerate(idx):
        ax = fig.add_subplot(grid[1, k])
        img, extent = stills[i]
        ax.imshow(img, extent=tuple(extent), interpolation="nearest" if img.shape[1] < 200 else "antialiased")
        _draw_measurement(ax, m, track, fitted, i, inside)
        if len(mended):
            ax.plot(strays[:, 0], strays[:, 1], "x", color="0.6", ms=5,
                    label=f"{len(mended)} frame{'s' if len(mended) != 1 else ''} off the path, read from their neighbours")
        shown = view or _whole(extent, m)
        ax.set_xlim(shown[0], shown[2])
        ax.set_ylim(shown[3], shown[1])
        what = "the pieces" if pieces and pieces.get("pieces") else "the stretch"
        where = "" if stretch is None else (f"(in {what})" if inside[i] else f"(outside {what})")
        # a narrow column (a tall view: a fall's strip) has no room for the title on one line
        frame = int(source_frames[i]) if source_frames is not None else i
        parts = [f"t = {t[i]:.2f} s", f"frame {frame}"] + ([where] if where else [])
        ax.set_title(("\n" if width / cols < 3.2 else "  ").join(parts), fontsize=8)
        ax.tick_params(labelsize=6)
        if k == 0:
            ax.set_ylabel("y (source pixels)", fontsize=7)
        ax.set_xlabel("x (source pixels)", fontsize=7)
    if idx:
        handles, labels = fig.axes[0].get_legend_handles_labels()
        key = fig.add_subplot(grid[0, :])
        key.axis("off")
        if handles:
            key.legend(handles, labels, loc="center", ncol=4, fontsize=7, frameon=False)
    for row, reading in enumerate(readings, start=2):
        ax = fig.add_subplot(grid[row, :])
        kept = reading.measured.copy()
        kept[mended] = np.nan
        ax.plot(t, kept, ".", ms=3, color="tab:blue", label="measured")
        if len(mended):
            ax.plot(t[mended], reading.measured[mended], "x", color="0.6", ms=5, label="off the path (not fitted)")
        ok = np.isfinite(reading.fitted)
        # with its gaps (pieces: the frames of a bounce are on no trajectory), not a line across them
        ax.plot(t, reading.fitted, "-", lw=1.3, color="tab:orange", label="the equation's fitted trajectory")
        _shade_stretch(ax, t, stretch if not pieces else None, train_frames)
        _mark_pieces(ax, t, pieces)
        for i in idx:
            ax.axvline(t[i], color="0.5", lw=0.6, ls=":")
        lo, hi = _limits(kept, reading.fitted[ok])
        ax.set_ylim(lo, hi)
        ax.set_ylabel(f"{reading.state}: {reading.label}", fontsize=8)
        a, b = reading.latent_map
        if calibrated and reading.state in calibrated and math.isfinite(a) and a != 0:
            big_a, big_b = calibrated[reading.state]
            k = big_a / a  # state = A * (reading - b) / a + B: affine in the reading
            if k != 0:
                ax.secondary_yaxis("right", functions=(lambda v, k=k, c=big_b - k * b: k * v + c,
                                                       lambda v, k=k, c=big_b - k * b: (v - c) / k)) \
                    .set_ylabel(f"{reading.state} calibrated (units of --calibrate)", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best", framealpha=0.85)
        if row == n_rows:
            ax.set_xlabel("time (s)")
    kind = m.get("kind", "none")
    text = NO_PLACE.get(kind) if not readings else None
    if not m:
        text = "the observation model recorded nothing to draw on the frames"
    title = f"what was measured ({kind}{', ' + _states_text(m) if m.get('states') and kind not in NO_PLACE else ''})"
    fig.suptitle(title + ("\n" + _wrap(text) if text else ""), fontsize=9)
    return _save(fig, path)


def _states_text(m: Mapping[str, Any]) -> str:
    return "; ".join(f"{s} read as {how}" for s, how in m["states"].items())


def _wrap(text: str, width: int = 120) -> str:
    import textwrap
    return "\n".join(textwrap.wrap(text, width))


def _xy(points, n: int) -> np.ndarray:
    xy = np.full((n, 2), np.nan)
    for i, p in enumerate((points or [])[:n]):
        if p is not None:
            xy[i] = p
    return xy


def _in_stretch(stretch: Mapping[str, Any] | None, n: int, pieces: Mapping[str, Any] | None = None) -> np.ndarray:
    """(n,) True for the frames fitted: the pieces' where there are pieces, else the stretch's."""
    inside = np.ones(n, dtype=bool)
    spans = (pieces or {}).get("pieces") or ([(stretch["start_frame"], stretch["end_frame"])] if stretch else [])
    if spans:
        inside[:] = False
        for a, b in spans:
            inside[max(int(a), 0): min(int(b), n)] = True
    return inside


def _shade_stretch(ax, t: np.ndarray, stretch: Mapping[str, Any] | None, train_frames: int | None) -> None:
    if stretch:
        a, b = int(stretch["start_frame"]), min(int(stretch["end_frame"]), len(t)) - 1
        if 0 <= a <= b:
            ax.axvspan(t[a], t[b], color="tab:green", alpha=0.12, zorder=0,
                       label=f"the stretch fitted ({stretch.get('source', 'found')})")
    if train_frames is not None and 0 < train_frames < len(t):
        ax.axvspan(t[train_frames], t[-1], color="0.85", zorder=0, label="not trained on")


EVENT_COLOURS = {"hold": "tab:purple", "moved": "tab:purple", "push": "tab:brown", "release": "tab:green",
                 "enter": "tab:green",
                 "bounce": "tab:red",
                 "stop": "0.3", "lost": "0.3", "gone": "0.3"}


def _mark_pieces(ax, t: np.ndarray, pieces: Mapping[str, Any] | None) -> None:
    """Each piece shaded (the constants are fitted to all of them together) and each event a line."""
    from fitode.train.pieces import ENDS

    if not pieces or not pieces.get("pieces"):
        return
    n = len(t)
    for k, (a, b) in enumerate(pieces["pieces"]):
        a, b = max(int(a), 0), min(int(b), n) - 1
        if a <= b:
            ax.axvspan(t[a], t[b], color="tab:green", alpha=0.12, zorder=0,
                       label=(f"the {len(pieces['pieces'])} pieces fitted together" if len(pieces["pieces"]) > 1
                              else "the stretch fitted") if k == 0 else None)
    seen = set()
    for e in pieces.get("events", ()):
        f = int(e["frame"])
        if e["kind"] == "release" or not 0 <= f < n:
            continue
        label = {"hold": "held until", "moved": "moved by something else until", "push": "pushed until",
                 "bounce": "a bounce",
                 "enter": "whole in the view from",
                 **ENDS}.get(e["kind"], e["kind"])
        ax.axvline(t[f], color=EVENT_COLOURS.get(e["kind"], "0.3"), lw=1.0, ls="--",
                   label=label if e["kind"] not in seen else None)
        seen.add(e["kind"])


def _whole(extent: Sequence[float], m: Mapping[str, Any]) -> tuple[float, float, float, float]:
    """The whole frame (left, top, right, bottom), reaching up to a pivot above it."""
    left, right, bottom, top = extent
    if m.get("pivot") is not None:
        top = min(top, m["pivot"][1] - 10)
    return left, top, right, bottom


def _view(m: Mapping[str, Any], track: np.ndarray, fitted, stills) -> tuple[float, float, float, float] | None:
    """The part of the frame to show: what was drawn, with a margin, in a shape no narrower than
    1:2 (a fall is a tall, thin path); None: the whole frame."""
    xs, ys = [], []
    for pts in (track, fitted):
        if pts is not None:
            ok = np.isfinite(pts).all(axis=1)
            xs += list(pts[ok, 0])
            ys += list(pts[ok, 1])
    if not xs and m.get("pivot") is None:  # nothing but a region: the whole frame says more
        return None
    if m.get("region"):
        x0, y0, x1, y1 = m["region"]
        xs += [x0, x1]
        ys += [y0, y1]
    if m.get("pivot") is not None:
        xs.append(m["pivot"][0])
        ys.append(m["pivot"][1])
    if not xs or not stills:
        return None
    left, right, bottom, top = next(iter(stills.values()))[1]
    w_img, h_img = right - left, bottom - top
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    w, h = max(x1 - x0, 1.0), max(y1 - y0, 1.0)
    # at least a quarter of the frame: the measurement is judged against what is around it
    w, h = max(w, 0.5 * h, 0.25 * w_img), max(h, 0.5 * w, 0.25 * h_img)
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    w, h = 1.4 * w, 1.4 * h
    if w >= 0.8 * w_img and h >= 0.8 * h_img:
        return None
    # a pivot above the frame stays in view; otherwise keep to the frame
    lo_y = min(top, cy - h / 2) if m.get("pivot") is not None else top
    return (max(left, cx - w / 2), max(lo_y, cy - h / 2), min(right, cx + w / 2), min(bottom, cy + h / 2))


def _draw_measurement(ax, m: Mapping[str, Any], track: np.ndarray, fitted, i: int, inside: np.ndarray) -> None:
    crop = m.get("crop")
    size = m.get("source_size")
    if crop and size and (crop[2] < size[0] - 8 or crop[3] < size[1] - 8):
        ax.add_patch(_rect(crop[0] - 0.5, crop[1] - 0.5, crop[0] + crop[2] - 0.5, crop[1] + crop[3] - 0.5,
                           "white", ":", "the crop read (--roi)"))
    if m.get("region"):
        ax.add_patch(_rect(*m["region"], "yellow", "-", REGION_LABEL.get(m.get("kind"), "the region measured")))
    if m.get("line"):
        p0, d = np.asarray(m["line"]["point"], float), np.asarray(m["line"]["direction"], float)
        ok = np.isfinite(track).all(axis=1)
        along = (track[ok] - p0) @ d if ok.any() else np.array([-50.0, 50.0])
        span = np.array([along.min(), along.max()]) + np.array([-0.15, 0.15]) * max(np.ptp(along), 10.0)
        ends = p0 + span[:, None] * d
        ax.plot(ends[:, 0], ends[:, 1], "--", color="cyan", lw=0.9, label="the line of motion")
    if np.isfinite(track).any():
        ax.plot(track[:, 0], track[:, 1], "-", color="white", lw=0.5, alpha=0.4)
        shown = np.where(inside[:, None], track, np.nan)
        ax.plot(shown[:, 0], shown[:, 1], ".-", color="lime", lw=0.5, ms=2.5, alpha=0.9,
                label="the tracked path (a dot per frame)")
    if fitted is not None and np.isfinite(fitted).any():
        ax.plot(fitted[:, 0], fitted[:, 1], "--", color="tab:orange", lw=1.1, label="the equation's trajectory")
        if np.isfinite(fitted[i]).all():
            ax.plot(*fitted[i], "x", color="tab:orange", ms=8, mew=2)
    if m.get("pivot") is not None:
        px, py = m["pivot"]
        ax.plot(px, py, "P", color="magenta", ms=9, label="the fitted pivot")
        if np.isfinite(track[i]).all():
            ax.plot([px, track[i, 0]], [py, track[i, 1]], "-", color="magenta", lw=1.0)
            ax.plot([px, px], [py, py + (m.get("radius") or np.hypot(*(track[i] - (px, py))))], ":",
                    color="magenta", lw=0.8)
        if m.get("radius"):
            a = np.linspace(0, 2 * np.pi, 200)
            ax.plot(px + m["radius"] * np.sin(a), py + m["radius"] * np.cos(a), "-", color="magenta", lw=0.5,
                    alpha=0.4, label=f"radius {m['radius']:.0f} px")
    radii = m.get("radii")
    if radii and i < len(radii) and radii[i] is not None and np.isfinite(track[i]).all():
        a = np.linspace(0, 2 * np.pi, 100)
        ax.plot(track[i, 0] + radii[i] * np.cos(a), track[i, 1] + radii[i] * np.sin(a), "-", color="red", lw=1.0,
                label="the apparent radius")
    if np.isfinite(track[i]).all():
        ax.plot(*track[i], "o", mfc="none", mec="red", ms=9, mew=1.6, label="measured in this frame")


def _rect(x0: float, y0: float, x1: float, y1: float, colour: str, style: str, label: str):
    from matplotlib.patches import Rectangle
    return Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec=colour, ls=style, lw=1.2, label=label)
