"""Does a latent tell the frames apart? The restart score that judges where the loss cannot.

A true state is a function of the frame that separates frames that look different. A latent
that solves the equation but not the video does not: z = x^2 (minus its mean) oscillates at
exactly twice the pendulum's frequency, an exact solution with L/4 that the loss may prefer,
and it maps the left and the right swing onto one value. The score asks how well the latent
predicts what the frames look like: the frames' leading principal components are regressed on
the standardised latent by k nearest neighbours, leaving out each frame's temporal neighbours
(which look alike whatever the latent is), and the score is the R^2 of that prediction, pooled
over the components. A right latent scores near 1, a folded one near 0 or below, a latent of
pixel noise or of a static scene near 0.

Monotone dynamics (a decay) are not judged by it: every monotone re-parametrisation of a
monotone state is injective, so it scores as well as the truth.
"""
from __future__ import annotations

import numpy as np

NEIGHBOURS = 5
NYQUIST_FRAMES = 2.5


def separation_score(latent: np.ndarray, coefs: np.ndarray, exclude: int, neighbours: int = NEIGHBOURS) -> float:
    """R^2 of predicting coefs (T, k) from the standardised latent (T, d) by the mean of the
    nearest neighbours in latent space, never using frames within `exclude` frames in time."""
    z = np.asarray(latent, dtype=float)
    if z.ndim == 1:
        z = z[:, None]
    n = len(z)
    if not np.all(np.isfinite(z)) or n < 2 * exclude + neighbours + 2:
        return float("nan")
    sd = z.std(axis=0)
    if not np.all(sd > 1e-12):
        return 0.0  # a constant latent tells nothing apart
    z = (z - z.mean(axis=0)) / sd
    dist = ((z[:, None, :] - z[None, :, :]) ** 2).sum(-1)
    t = np.arange(n)
    dist[np.abs(t[:, None] - t[None, :]) <= exclude] = np.inf
    nearest = np.argpartition(dist, neighbours, axis=1)[:, :neighbours]
    pred = coefs[nearest].mean(axis=1)
    sse = ((coefs - pred) ** 2).sum()
    sst = ((coefs - coefs.mean(axis=0)) ** 2).sum()
    return float(1.0 - sse / sst) if sst > 0 else 0.0


def dominant_period(series: np.ndarray, dt: float) -> float | None:
    """The period (s) of the strongest oscillation of a (T,) or (T, k) series, pooled over its
    columns; None when there is no peak below the Nyquist frequency that stands above a full cycle."""
    x = np.asarray(series, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if len(x) < 8 or not np.all(np.isfinite(x)):
        return None
    x = x - x.mean(axis=0)
    n = len(x)
    pad = 8 * n  # zero padding interpolates the spectrum between its bins
    power = (np.abs(np.fft.rfft(x * np.hanning(n)[:, None], n=pad, axis=0)) ** 2).sum(axis=1)
    freqs = np.fft.rfftfreq(pad, dt)
    lo = 1.5 / (n * dt)  # at least one and a half cycles in the clip
    # and at least NYQUIST_FRAMES frames a cycle: a peak at two frames is flicker (a codec's
    # alternate frames: a generated oscillator's frames "repeated every 2 frames" with the
    # latent and the equation agreeing on 16), no motion the frames can show
    ok = (freqs > lo) & (freqs < 1.0 / (NYQUIST_FRAMES * dt))
    if not ok.any() or power[ok].max() <= 0:
        return None
    band = power[ok]
    k = int(np.argmax(band))
    # a monotone drift leaks power into the lowest frequencies: only a peak that rises well above
    # the low edge of the band is an oscillation
    if k == 0 or band[k] < 2 * band[0]:
        return None
    return float(1.0 / freqs[ok][k])
