"""How much the frames change between frames k apart: the structure function and its motion part.

The measure that both the stride (fitode.stride: how far apart to take frames) and the training
window (train/window.py: how many of them one window spans) read. It lives here, below both,
because training must not import the command-line layer.

The structure function of a sequence is

    D(k) = mean over t and pixels of (f[t+k] - f[t])^2,

the mean squared change between frames k apart, for every lag k at once (FFT, O(N log N) per
pixel, streamed over pixel chunks so memory stays small). Sensor and compression noise that is
independent from frame to frame adds a constant 2*sigma^2 to every D(k); `motion_rms` removes it,
leaving r(k), the RMS change due to motion.
"""
from __future__ import annotations

import numpy as np

_CHUNK_BYTES = 16 * 2**20


def structure_function(frames: np.ndarray) -> np.ndarray:
    """D(k) for k = 0..N-1: mean over pairs and pixels of (f[t+k] - f[t])^2.

    `frames` is (N, ...) with any trailing shape; every trailing element is a pixel.
    Uses D(k) = [sum_t g[t+k]^2 + g[t]^2 - 2 g[t] g[t+k]] / ((N-k) P) with g the frames minus
    their temporal mean (which leaves differences unchanged but avoids cancellation); the cross
    term is the autocorrelation, summed over pixels in the frequency domain.
    """
    n = int(frames.shape[0])
    flat = frames.reshape(n, -1)
    n_pix = flat.shape[1]
    if n == 0 or n_pix == 0:
        return np.zeros(n)
    nfft = 1 << max(1, (2 * n - 1).bit_length())  # zero-padded: linear, not circular, correlation
    power = np.zeros(nfft // 2 + 1)
    sq = np.zeros(n)
    chunk = max(1, _CHUNK_BYTES // (nfft * 24))
    for j in range(0, n_pix, chunk):
        g = flat[:, j:j + chunk].astype(np.float64)
        g -= g.mean(axis=0)
        sq += np.einsum("tp,tp->t", g, g)
        spec = np.fft.rfft(g, n=nfft, axis=0)
        power += np.einsum("fp,fp->f", spec.real, spec.real)
        power += np.einsum("fp,fp->f", spec.imag, spec.imag)
    cross = np.fft.irfft(power, n=nfft)[:n]
    prefix = np.concatenate([[0.0], np.cumsum(sq)])
    k = np.arange(n)
    pairs = n - k
    both = (prefix[n] - prefix[k]) + prefix[n - k]
    d = (both - 2.0 * cross) / (pairs * n_pix)
    return np.maximum(d, 0.0)


def search_lags(n: int) -> int:
    """The longest lag that sets the scale of the change in n frames: 2N/3, so at least N/3 pairs
    of frames measure each lag."""
    return max(3, (2 * n) // 3)


def motion_rms(d: np.ndarray, last_lag: int) -> tuple[np.ndarray, float]:
    """r[i], the RMS change due to motion at lag i+1 for lags 1..last_lag, from the structure
    function d, and the noise variance removed. Noise independent between frames adds the same
    2 sigma^2 at every lag; it is extrapolated to lag 0 from D(1) and D(2), which underestimates
    it slightly for smooth motion (erring towards smaller strides and shorter windows)."""
    noise = float(np.clip(2.0 * d[1] - d[2], 0.0, d[1]))
    return np.sqrt(np.maximum(d[1:last_lag + 1] - noise, 0.0)), noise
