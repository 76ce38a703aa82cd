"""How residuals hang together in time: the lag-one correlation and the integrated
autocorrelation time, read by the interval's block bootstrap (interval.py) and by the circle
fit's covariance (observe/circle.py)."""
from __future__ import annotations

import numpy as np

MAX_RHO = 0.98  # a lag-one correlation is held under this: (1 + rho) / (1 - rho) stays finite


def correlation(residuals: np.ndarray) -> float:
    """The lag-one autocorrelation of the residuals, the largest over the states (0 to MAX_RHO)."""
    r = np.asarray(residuals, dtype=float).reshape(len(residuals), -1)
    r = r - r.mean(axis=0)
    rho = [float(r[1:, j] @ r[:-1, j] / (r[:, j] @ r[:, j])) for j in range(r.shape[1]) if r[:, j] @ r[:, j] > 0]
    return min(max(max(rho, default=0.0), 0.0), MAX_RHO)



def correlation_time(residuals: np.ndarray) -> float:
    """The integrated autocorrelation time of residuals (T, k) in samples: the larger of the sum
    of their autocorrelation over its initial positive run, Geyer's cut, and an AR(1)'s
    (1 + rho) / (1 - rho) from the lag-one correlation; the largest over the states."""
    r = np.asarray(residuals, dtype=float).reshape(len(residuals), -1)
    n = len(r)
    rho = correlation(r)
    tau = (1 + rho) / (1 - rho)
    for j in range(r.shape[1]):
        e = r[:, j] - r[:, j].mean()
        var = float(e @ e)
        if var <= 0:
            continue
        acf = np.correlate(e, e, mode="full")[n - 1:] / var
        s = 1.0
        for k in range(1, n // 2):
            if acf[k] <= 0:
                break
            s += 2 * acf[k]
        tau = max(tau, s)
    return tau


