"""A 95% interval for every constant, from what limits it.

The estimate is a set of constants for which one trajectory of the equation follows a path x
(T, k): a measured path, or a learned latent read as the equation's state. What limits it:

- the residuals. The fitted trajectory leaves residuals that hang together from frame to frame
  (motion blur, the codec, a tracker's wobble, what the equation leaves out), so a formula that
  counts T independent frames is too narrow, by a factor that grows with the correlation. The
  residuals are resampled in moving blocks along time (circular, centred), the blocks three times
  as long as the residuals stay correlated (block_length), added to the fitted trajectory and
  refitted from the estimate with a few Gauss-Newton steps that keep the estimate's Jacobian (a
  refit only moves as far as the noise moves the optimum; all refits are one batched rollout per
  step: fit_trajectory's L-BFGS took 8 s a refit for 300 frames here). The spread of the refits,
  corrected for what short blocks (block_bias) and the fit itself (leverage) take out of the
  residuals, is their share, and a Student t quantile for the few refits makes it a 95% one.
- the frame timing. Every constant scales with a power of time (a frequency squared, g/L); the
  refit of the same path with dt stretched by TIME_STEP gives that sensitivity for any equation,
  and a relative uncertainty of the frame rate (rate_std: the container's nominal rate, or 0 for
  a rate the user gave) adds its share.
- the calibration points (fitode.calibrate: value +- std), added by the caller as a relative share.
- the measurement's geometry. An angle is read about a fitted pivot, uncertain by its covariance
  (meta["measurement"]["pivot_cov"]): the path read again about the pivot moved by one standard
  deviation along each of its axes (observe.angle.pivot_moves) and refitted gives each constant's
  share (geometry; a large swing's L moves with the amplitude, its damping with the bend a pivot
  off along the hanging direction gives large angles). Where a measurement gives only a relative
  scale error (meta["measurement"]["scale_error"]), the refit of the path scaled by SCALE_STEP gives
  each constant's sensitivity to it instead.
- the restarts of a free latent: the spread of the kept restarts, widened by RESTART_WIDEN (few
  restarts say little of their own spread), the gap between the reported value and the one
  trajectory's (the training's windows see less than the whole clip), and what the latent's
  freedom to bend adds: each constant's change when the fitted trajectory is bent by BEND of its
  spread (bends; ONE_WAY_BEND where the latent runs one way), and a floor of ENCODER_FLOOR of
  its value.
- the rivals: a restart left out that tells the frames apart as well and fits its latent about as
  well but ended elsewhere (selection.rivals, which makes the verdict ambiguous) is a solution the
  clip cannot rule out, so the interval reaches the farthest of them (a drain through a free
  encoder: k +7.2% with +-1.5%, a rival restart 27% away).

The shares are independent and add in quadrature; the gap and the rival add as biases would. The interval does
not care how the estimate was found: it takes the system, the path, dt and the values.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from fitode.errors import FitodeError

from .residuals import correlation, correlation_time
from .selection import rivals


LEVEL = 0.95
ITERATIONS = 48  # refits, all in one batch
REFIT_ITERATIONS = 4  # chord (Gauss-Newton) steps per refit, from the one trajectory: the noise moves it little
CENTRE_ITERATIONS = 12  # Gauss-Newton steps from the estimate to the one trajectory
TIME_STEP = 0.001  # dt stretched by 0.1% to read each constant's sensitivity to the frame rate
SCALE_STEP = 0.001  # the path scaled by 0.1% to read each constant's sensitivity to the measurement's scale
RESTART_WIDEN = 2.0
# a learned (free) latent can bend where the frames do not hold it, which no residual shows (the
# bundled example's L 0.29% off with its restarts agreeing to 0.002%, the paper's motion video's g1
# 1.7% off with the residuals' share 0.08%): each constant's change under bends of BEND of the
# path's spread (bends()), and ENCODER_FLOOR of its value, are its share (both set on those two
# clips; the coverage bench checks them)
BEND = 0.01
ENCODER_FLOOR = 0.002
# a one-way path (a drain, a decay) bent by a free encoder is bent farther, unseen: nothing in the
# frames repeats to hold the readout straight, and the verdict calls it not trustworthy for that.
# Its bends are taken ONE_WAY_BEND of its spread (set on the generated drains of `coverage.py
# --cases drain`, k 1.5-6.4% high with the 1% bend's share at 0.4-0.7% of k). A linear readout
# (the brightness observation's, of a lamp's one pattern) cannot bend a path so: a lamp stored as
# linear light, 0.01% off, was given +-7% by it and called ambiguous
ONE_WAY_BEND = 0.05
# where the frames cannot tell the camera's light curve (light.choose_curve), a rate read through
# the sRGB curve would be smaller by up to the curve's power read as linear light: the interval of
# a rate reaches down that far (a linear-light lamp read as sRGB: gamma 0.998 for 0.574, with a
# +-4% interval that held nothing)
CURVE_POWER = 2.4
BLOCK_TIMES = 3  # blocks three autocorrelation times long: what is left is block_bias's
DAMPINGS = (1e-9, 1e-5, 1e-2, 1.0)  # Levenberg-Marquardt dampings tried at once, relative to the diagonal
HELD_OUT = 0.25  # the last quarter of the path, predicted from a fit of the rest
HELD_OUT_REPLICAS = 16  # ... and of as many of the bootstrap's paths, where the equation holds by construction
MIN_KEPT = 0.6  # fewer refits than this fraction succeeded: no interval from the residuals
RATE_CONTAINER_STD = 3e-4  # the container's nominal rate: 59.985 stated against 60.000 stamped (bob clip)
RATE_GIVEN_STD = 0.0  # --fps: the user states the rate


@dataclass
class Interval:
    """One constant's interval and the shares behind it (standard deviations, the constant's units)."""

    low: float
    high: float
    value: float
    shares: dict[str, float] = field(default_factory=dict)  # residuals, timing, calibration, restarts, gap

    @property
    def relative_width(self) -> float:
        return (self.high - self.low) / max(abs(self.value), 1e-300)

    def contains(self, v: float) -> bool:
        return self.low <= v <= self.high

    def to_dict(self) -> dict:
        return {"interval": [self.low, self.high], "shares": dict(self.shares)}


@dataclass
class Bootstrap:
    """The moving-block bootstrap of one path: each constant's residual and timing standard
    deviations, and how they were found."""

    values: dict[str, float]  # the one trajectory's constants (the bootstrap's centre)
    std: dict[str, float]  # the refits' spread
    timing: dict[str, float]  # d constant / d log(dt)
    block: int
    iterations: int
    kept: int
    quantile: float  # the t quantile the residual share is multiplied by
    wall_s: float
    misfit: float  # the one trajectory's RMS residual over each state's spread
    residual_rms: list[float]  # per state, in the path's units
    held_out: float | None = None  # the held-out prediction's miss over the residuals there (_held_out)
    held_out_null: float | None = None  # ... the largest of it over HELD_OUT_REPLICAS resampled paths
    held_out_values: dict[str, float] = field(default_factory=dict)  # the constants fitted without the quarter
    bend: dict[str, float] = field(default_factory=dict)  # the constants' RMS change under BEND-sized bends
    scaling: dict[str, float] = field(default_factory=dict)  # d constant / d log(the path's scale)
    geometry: dict[str, float] = field(default_factory=dict)  # the constants' std from the measurement's geometry (moves)

    def to_dict(self) -> dict:
        return {"method": "moving-block bootstrap of the one trajectory's residuals", "block": self.block,
                "iterations": self.iterations, "kept": self.kept, "t_quantile": self.quantile,
                "wall_s": self.wall_s, "trajectory": dict(self.values), "std": dict(self.std),
                "dlog_dt": dict(self.timing), "misfit": self.misfit, "residual_rms": list(self.residual_rms),
                "held_out": self.held_out, "held_out_null": self.held_out_null,
                "held_out_values": dict(self.held_out_values), "bend": dict(self.bend), "dlog_scale": dict(self.scaling),
                "geometry": dict(self.geometry)}


def block_length(residuals: np.ndarray) -> int:
    """BLOCK_TIMES the integrated autocorrelation time of the residuals (correlation_time), at
    least 1 and at most a quarter of the frames: a block must hold what hangs together, and
    there must be blocks to draw."""
    n = len(residuals)
    return int(min(max(1, math.ceil(BLOCK_TIMES * correlation_time(residuals))), max(1, n // 4)))


def block_bias(rho: float, block: int) -> float:
    """The factor by which blocks of `block` frames understate the spread of a sum of AR(1)
    residuals with lag-one correlation rho: a block loses the correlation across its edges
    (the bootstrap's variance is the Bartlett-weighted sum of the autocovariance up to the block,
    the truth the whole sum, (1 + rho) / (1 - rho))."""
    k = np.arange(1, max(block, 1))
    seen = 1 + 2 * float(np.sum((1 - k / block) * rho ** k))
    return math.sqrt(((1 + rho) / (1 - rho)) / seen)


def leverage(n: int, p: int, rho: float) -> float:
    """The factor by which residuals understate the noise: the fit takes p of the path's
    n / tau independent stretches (tau = (1 + rho) / (1 - rho)) into its constants and start,
    so the residuals keep only 1 - p tau / n of the noise's variance (a residual bootstrap's
    usual correction, 1 / sqrt(1 - h), for frames that hang together)."""
    tau = (1 + rho) / (1 - rho)
    return math.sqrt(1.0 / max(1.0 - p * tau / n, 0.25))


def resample_blocks(residuals: np.ndarray, block: int, rng: np.random.Generator) -> np.ndarray:
    """Circular moving blocks of the residuals, (T, k), centred so that the resampled residuals
    add no offset."""
    r = np.asarray(residuals, dtype=float)
    n = len(r)
    starts = rng.integers(0, n, size=math.ceil(n / block))
    idx = (starts[:, None] + np.arange(block)[None, :]).reshape(-1)[:n] % n
    out = r[idx]
    return out - out.mean(axis=0)


def t_quantile(level: float, dof: int) -> float:
    """Student's t quantile (two-sided `level`), from the normal one by the Cornish-Fisher series."""
    from statistics import NormalDist
    z = NormalDist().inv_cdf(0.5 + level / 2)
    if dof <= 0:
        return math.inf
    g1 = (z ** 3 + z) / 4
    g2 = (5 * z ** 5 + 16 * z ** 3 + 3 * z) / 96
    g3 = (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / 384
    return z + g1 / dof + g2 / dof ** 2 + g3 / dof ** 3


class _Batch:
    """Rollouts of one trajectory of the equation for many (constants, starting frames) at once:
    every draw and every finite-difference column is one row of a single NumPy rollout, so that a
    Gauss-Newton step for all draws is one rollout (a refit one by one with L-BFGS took 8 s for
    300 frames here; 64 draws at once take about as long as one)."""

    def __init__(self, system, params: Mapping, x: np.ndarray, dt: float, integrator: str, substeps: int,
                 pieces: Sequence[int] | None = None):
        import torch

        from fitode.codegen import PhysicsBlock

        self.system, self.params, self.dt = system, params, float(dt)
        self.integrator, self.substeps = integrator, substeps
        self.names = list(system.learnable)
        self.block = PhysicsBlock(system, params, integrator=integrator, substeps=substeps, dtype=torch.float64,
                                  check_finite=False)
        self.nc, self.T, self.k = self.block.n_context, x.shape[0], x.shape[1]
        # pieces: x is the frames of several trajectories one after another (train/pieces.py), each
        # with starting frames of its own and the constants shared; their lengths, summing to T
        self.lengths = [int(n) for n in pieces] if pieces else [self.T]
        if sum(self.lengths) != self.T or min(self.lengths) < self.nc + 1:
            raise ValueError("the pieces' lengths must cover the path, each longer than the context")
        self.firsts = np.concatenate([[0], np.cumsum(self.lengths)[:-1]]).astype(int)
        self.m = len(self.names)
        self.p = self.m + len(self.lengths) * self.nc * self.k
        self.weight = 1.0 / np.maximum(x.std(axis=0), 1e-24)  # every state counts equally, as fit_trajectory's
        self.state_weight = self.weight

    def enough(self) -> bool:
        """Enough frames for the refits: one trajectory twice as many beyond its starting frames as it
        has numbers to fit; several pieces, whose starting frames are only read for a state, two
        rolled-out frames per piece and per constant (three flights of a ball filmed at 30 fps are
        28 frames, and 16 numbers with their starting frames)."""
        if len(self.lengths) == 1:
            return self.T >= self.nc + 2 * self.p
        return self.T - len(self.lengths) * self.nc >= 2 * (self.m + len(self.lengths))

    def weigh_pieces(self, resid: np.ndarray) -> np.ndarray:
        """Weigh each piece by its own noise, from the residuals (T, k) of a fit: a flight read
        near the bumper, or a bounce far from the camera, is measured less well than another, and
        pooled with it would both widen the interval and pull the constants its way. Returns each
        frame's residual spread relative to all pieces' (T, k; ones for one piece), by which the
        weight is divided; a piece's spread counts the starting frames its own fit took up."""
        rel = np.ones_like(resid)
        if len(self.lengths) > 1:
            pooled = np.sqrt(np.mean(resid ** 2, axis=0))
            for f, n in zip(self.firsts, self.lengths):
                own = np.sqrt(np.mean(resid[f:f + n] ** 2, axis=0) * n / max(n - self.nc, 1))
                rel[f:f + n] = np.maximum(own, 1e-3 * pooled) / np.maximum(pooled, 1e-300)
        self.weight = self.state_weight / rel
        return rel

    def starts(self, x: np.ndarray) -> np.ndarray:
        """The starting frames of every piece of x (T, k), flat, as theta carries them."""
        return np.concatenate([x[f:f + self.nc].reshape(-1) for f in self.firsts])

    def roll(self, theta: np.ndarray, dt: float | None = None, frames: int | None = None) -> np.ndarray:
        """(N, T, k) trajectories for theta (N, p) = constants then starting frames (each piece's);
        NaN where a rollout leaves the equation's domain. A constant at or beyond its bound is moved
        just inside it (codegen.Reparam.clip); one that is not a number is a ParameterError.
        frames: a longer rollout (one piece only)."""
        n, P = len(theta), len(self.lengths)
        values = [np.repeat(_inside(self.block, name, theta[:, i]), P) for i, name in enumerate(self.names)]
        head = theta[:, self.m:].reshape(n * P, self.nc, self.k)
        out = self.block.rollout_numpy(head, frames or max(self.lengths), self.dt if dt is None else dt, values)
        if P == 1:
            return out if frames else out[:, :self.T]
        out = out.reshape(n, P, -1, self.k)
        return np.concatenate([out[:, j, :length] for j, length in enumerate(self.lengths)], axis=1)

    def steps(self, theta: np.ndarray) -> np.ndarray:
        """Finite-difference steps (N, p): relative for the constants, a millionth of each
        state's spread for the starting frames."""
        h = np.empty_like(theta)
        h[:, : self.m] = 1e-6 * np.maximum(np.abs(theta[:, : self.m]), 1e-6)
        h[:, self.m:] = np.tile(1e-6 / self.state_weight, self.nc * len(self.lengths))[None, :]
        return h

    def cost(self, theta: np.ndarray, targets: np.ndarray) -> np.ndarray:
        r = (self.roll(theta) - targets) * self.weight
        c = np.mean(r.reshape(len(theta), -1) ** 2, axis=1)
        return np.where(np.isfinite(c), c, np.inf)

    def jacobian(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rollouts (N, T, k) at theta (N, p) and their weighted Jacobians (N, p, T*k), by
        forward differences, all in one batched rollout."""
        h = self.steps(theta)
        batch = np.repeat(theta[:, None, :], self.p + 1, axis=1)
        batch[:, 1:, :] += np.eye(self.p)[None] * h[:, None, :]
        rolled = self.roll(batch.reshape(-1, self.p)).reshape(len(theta), self.p + 1, self.T, self.k)
        jac = ((rolled[:, 1:] - rolled[:, :1]) * self.weight / h[:, :, None, None]).reshape(len(theta), self.p, -1)
        return rolled[:, 0], jac

    def gauss_newton(self, theta: np.ndarray, targets: np.ndarray, iterations: int) -> np.ndarray:
        """Levenberg-Marquardt steps of every theta (N, p) towards its target (N, T, k): each
        step tries DAMPINGS in one rollout and keeps the one that lowers the misfit most (none:
        theta stays); stops early once no step gains; NaN where the rollout fails."""
        theta = theta.copy()
        n, tries = len(theta), len(DAMPINGS)
        eye = np.eye(self.p)[None, None]
        for _ in range(iterations):
            rolled, jac = self.jacobian(theta)
            r = ((rolled - targets) * self.weight).reshape(n, -1)
            normal = jac @ jac.transpose(0, 2, 1)
            grad = (jac @ r[:, :, None])[:, :, 0]
            now = np.mean(r ** 2, axis=1)
            ok = np.all(np.isfinite(normal.reshape(n, -1)), axis=1) & np.isfinite(now)
            if not ok.any():
                return np.full_like(theta, np.nan)
            normal[~ok], grad[~ok] = np.eye(self.p), 0.0
            diag = np.maximum(np.einsum("nii->ni", normal), 1e-300)
            lhs = normal[:, None] + (np.asarray(DAMPINGS)[None, :, None] * diag[:, None, :])[..., None] * eye
            # pinv: at a near-exact fit the starting frames' columns can be all but collinear
            trial = theta[:, None, :] - (np.linalg.pinv(lhs, rcond=1e-13) @ grad[:, None, :, None])[..., 0]
            costs = self.cost(trial.reshape(-1, self.p), np.repeat(targets, tries, axis=0)).reshape(n, tries)
            pick = np.argmin(costs, axis=1)
            gain = now - costs[np.arange(n), pick]
            better = ok & (gain > 0)
            theta = np.where(better[:, None], trial[np.arange(n), pick], theta)
            theta[~ok] = np.nan
            if np.all(~better | (gain <= 1e-12 * np.maximum(now, 1e-300))):
                break
        return theta

    def chord(self, centre: np.ndarray, targets: np.ndarray, iterations: int) -> np.ndarray:
        """Refits of many targets near the centre's trajectory (N, T, k) from the centre (1, p):
        Gauss-Newton steps with the centre's Jacobian kept (the chord method: a refit moves
        little, and one Jacobian for every refit makes each step one rollout per refit, not
        p + 1). A step that raises a refit's misfit (by more than rounding) is taken back and the refit stops there; a
        refit whose first step already does is NaN, as is one whose rollout fails: the centre's
        linearisation does not reach its target (a learned latent with residuals of a fifth of
        its spread sent a pendulum's refits to L = 4000 for 0.3, and the interval to +-28000)."""
        _, jac = self.jacobian(centre)
        solve = np.linalg.pinv(jac[0] @ jac[0].T, rcond=1e-13) @ jac[0]  # (p, T*k)
        n = len(targets)
        theta = np.repeat(centre, n, axis=0)
        frozen, lost = np.zeros(n, bool), np.zeros(n, bool)
        before = cost = None
        for it in range(iterations + 1):
            r = ((self.roll(theta) - targets) * self.weight).reshape(n, -1)
            now = np.mean(r ** 2, axis=1)
            now = np.where(np.isfinite(now), now, np.inf)
            if before is not None:
                worse = ~frozen & (now > cost * (1 + 1e-3) + 1e-300)  # not a rounding's rise at the optimum
                theta[worse], now[worse] = before[worse], cost[worse]
                lost |= worse & (it == 1)
                frozen |= worse
            if it == iterations:
                break
            before, cost = theta.copy(), now
            step = np.where(np.isfinite(r), r, 0.0) @ solve.T
            theta = np.where(frozen[:, None], theta, theta - step)
        theta[lost | ~np.isfinite(now)] = np.nan
        return theta


def _inside(block, name: str, v: np.ndarray) -> np.ndarray:
    """v moved strictly inside the constant's bounds, as codegen.Reparam.clip moves one value."""
    from fitode.codegen import ParameterError
    v = np.asarray(v, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise ParameterError(f"{name}: a value is not finite")
    lo, hi = block.bounds(name)
    if lo is not None and hi is not None:
        margin = 1e-6 * (hi - lo)
        return np.clip(v, lo + margin, hi - margin)
    if lo is not None:
        return np.where(v <= lo, lo + 1e-6 * max(1.0, abs(lo)), v)
    if hi is not None:
        return np.where(v >= hi, hi - 1e-6 * max(1.0, abs(hi)), v)
    return v


def bootstrap(system, params: Mapping, x: np.ndarray, dt: float, values: Mapping[str, float], *,
              iterations: int = ITERATIONS, seed: int = 0, integrator: str = "rk4", substeps: int = 1,
              refit_iterations: int = REFIT_ITERATIONS, level: float = LEVEL,
              learned: bool = False, moves: list[np.ndarray] | None = None,
              pieces: Sequence[int] | None = None, scatter: Mapping[str, float] | None = None) -> Bootstrap | None:
    """The moving-block bootstrap of the path x (T, k) about one trajectory of the equation
    fitted from `values` (see the module docstring). learned: x is a learned latent, whose
    bends are measured too (bends). moves: changes of the path (T, k), each one standard deviation
    of the measurement's geometry along an independent direction (an angle's pivot: angle.pivot_moves);
    the refits of the path so changed give each constant's share (geometry). None where the path
    cannot be fitted as one trajectory or too few refits succeed. pieces: x is several trajectories
    one after another, these many frames each, with the constants shared (train/pieces.py);
    scatter: per constant, how much farther the pieces alone scatter than their errors say
    (train/joint.py), by which its residual share is widened."""
    began = time.perf_counter()
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    if not np.all(np.isfinite(x)):
        return None
    try:
        # a refit that runs off overflows on its way to NaN, which is dropped below: not a warning
        with np.errstate(over="ignore", invalid="ignore"):
            batch = _Batch(system, params, x, dt, integrator, substeps, pieces)
            drawn = _resampled(batch, x, values, iterations, seed, refit_iterations)
            if drawn is None:
                return None
            centre, fitted, resid, rel, block, targets, draws = drawn
            stretched = batch.gauss_newton(centre, batch.roll(centre, dt * (1 + TIME_STEP)), refit_iterations)
            scaled = batch.chord(centre, fitted[None] * (1 + SCALE_STEP), refit_iterations)
            held_out, held_null, without = _held_out(system, params, x, dt, centre, integrator, substeps,
                                                     targets[:HELD_OUT_REPLICAS]) \
                if len(batch.lengths) == 1 else (None, None, None)
            bend = bends(batch, centre, fitted, refit_iterations) if learned else {}
            moved = batch.chord(centre, fitted[None] + np.stack(moves), refit_iterations) if moves else None
    except (ValueError, RuntimeError, FloatingPointError, np.linalg.LinAlgError, FitodeError):
        return None  # (FitodeError: a refit ran a constant off to no number, on a path of noise)
    names, m = batch.names, batch.m
    rho = correlation(resid / rel)
    spread = np.std(draws[:, :m], axis=0, ddof=1) * block_bias(rho, block) * leverage(len(x), batch.p, rho)
    spread = spread * np.array([float((scatter or {}).get(n, 1.0)) for n in names])
    # the same path read with a longer dt: the constants that make the stretched-time rollout
    # match it, i.e. the constants' sensitivity to the frame rate (a pure power of time or not)
    timing = {n: float((centre[0, i] - stretched[0, i]) / math.log1p(TIME_STEP)) for i, n in enumerate(names)}
    scaling = {n: float((scaled[0, i] - centre[0, i]) / math.log1p(SCALE_STEP)) for i, n in enumerate(names)
               if math.isfinite(scaled[0, i])}
    geometry = ({n: float(np.sqrt(np.sum((moved[:, i] - centre[0, i]) ** 2))) for i, n in enumerate(names)
                 if np.all(np.isfinite(moved[:, i]))} if moved is not None else {})
    return Bootstrap(values={n: float(centre[0, i]) for i, n in enumerate(names)},
                     std={n: float(s) for n, s in zip(names, spread)}, timing=timing, block=block,
                     iterations=iterations, kept=len(draws), quantile=t_quantile(level, len(draws) - 1),
                     wall_s=time.perf_counter() - began,
                     misfit=float(np.sqrt(np.mean((resid * batch.state_weight) ** 2))),
                     residual_rms=[float(v) for v in np.sqrt(np.mean(resid ** 2, axis=0))],
                     held_out=held_out, held_out_null=held_null,
                     held_out_values={n: float(without[i]) for i, n in enumerate(names)} if without is not None else {},
                     bend=bend, scaling=scaling, geometry=geometry)


def _resampled(batch: _Batch, x: np.ndarray, values: Mapping[str, float], iterations: int, seed: int,
               refit_iterations: int):
    """The one trajectory fitted to x (T, k) from values and the refits of its moving-block
    resamples: (centre (1, p), fitted (T, k), residuals, each frame's relative noise, block,
    the resampled paths, the refits (N, p) that came out finite); None where too few did."""
    if not batch.enough():
        return None
    theta0 = np.concatenate([[float(values[n]) for n in batch.names], batch.starts(x)])[None]
    centre = batch.gauss_newton(theta0, x[None], CENTRE_ITERATIONS)
    if not np.all(np.isfinite(centre)):
        return None
    if len(batch.lengths) > 1:  # each piece weighed by its own noise, and resampled at it
        rel = batch.weigh_pieces(x - batch.roll(centre)[0])
        centre = batch.gauss_newton(centre, x[None], CENTRE_ITERATIONS)
        if not np.all(np.isfinite(centre)):
            return None
    else:
        rel = np.ones_like(x)
    fitted = batch.roll(centre)[0]
    resid = x - fitted
    block = block_length(resid / rel)
    rng = np.random.default_rng(seed)
    targets = np.stack([fitted + resample_blocks(resid / rel, block, rng) * rel for _ in range(iterations)])
    draws = batch.chord(centre, targets, refit_iterations)
    draws = draws[np.all(np.isfinite(draws), axis=1)]
    if len(draws) < max(2, MIN_KEPT * iterations):
        return None
    return centre, fitted, resid, rel, block, targets, draws


def trajectory_moves(system, params: Mapping, x: np.ndarray, dt: float, values: Mapping[str, float], *,
                     iterations: int = ITERATIONS, seed: int = 0, integrator: str = "rk4",
                     substeps: int = 1) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]] | None:
    """How far the one trajectory fitted to the path x (T, k) moves with the path's residuals: the
    trajectory (T, k), each refit's (bootstrap's draws, rolled out) difference from it (N, T, k),
    and each constant's difference in the same refits ({name: (N,)}), all widened as the
    constants' spread is (block_bias, leverage). What a reading taken on the fitted trajectory is
    uncertain by, and how that hangs together with the constants fitted to the same path
    (fitode.calibrate reads its points there). None where it cannot be made."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    if not np.all(np.isfinite(x)):
        return None
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            batch = _Batch(system, params, x, dt, integrator, substeps)
            drawn = _resampled(batch, x, values, iterations, seed, REFIT_ITERATIONS)
            if drawn is None:
                return None
            centre, fitted, resid, _, block, _, draws = drawn
            rolled = batch.roll(draws)
    except (ValueError, RuntimeError, FloatingPointError, np.linalg.LinAlgError, FitodeError):
        return None
    ok = np.all(np.isfinite(rolled), axis=(1, 2))
    if ok.sum() < 2:
        return None
    rho = correlation(resid)
    widen = block_bias(rho, block) * leverage(len(x), batch.p, rho)
    constants = {n: (draws[ok, i] - centre[0, i]) * widen for i, n in enumerate(batch.names)}
    return fitted, (rolled[ok] - fitted[None]) * widen, constants


def bends(batch: _Batch, centre: np.ndarray, fitted: np.ndarray, iterations: int) -> dict[str, float]:
    """Each constant's RMS change when the fitted trajectory is bent by BEND of its spread in the
    ways a learned latent can bend unseen: its amplitude growing or shrinking along the clip, and
    a quadratic and a cubic bend of its values (a readout slightly off a straight line)."""
    mid = fitted.mean(axis=0)
    half = np.maximum(np.abs(fitted - mid).max(axis=0), 1e-300)
    u = (fitted - mid) / half
    ramp = np.linspace(-1.0, 1.0, len(fitted))[:, None]
    shapes = [u * ramp, u * np.abs(u), u ** 3]
    targets = np.stack([fitted + BEND * half * s for s in shapes])
    bent = batch.chord(centre, targets, iterations)
    change = bent[:, : batch.m] - centre[:, : batch.m]
    if not np.all(np.isfinite(change)):
        return {}
    return {n: float(np.sqrt(np.mean(change[:, i] ** 2))) for i, n in enumerate(batch.names)}


def _held_out(system, params: Mapping, x: np.ndarray, dt: float, centre: np.ndarray, integrator: str,
              substeps: int, replicas: np.ndarray | None = None) -> tuple[float | None, float | None]:
    """How much worse the equation predicts the last HELD_OUT of the path, fitted without it,
    than the one trajectory fitted to all of it follows it there: the RMS of the prediction's
    miss over the RMS of the one trajectory's residuals on the same frames (about 1 where the
    equation explains the clip and its residuals are white; None where the rest cannot be fitted);
    and the largest such ratio over `replicas` (N, T, k): the one trajectory with its residuals
    resampled in blocks, which the equation explains by construction. Residuals that hang together
    over many frames (a tracker's slow error, 4 times the frame-to-frame noise on a released swing)
    move a short fit's prediction by several times themselves: that is the size the ratio reaches
    without any fault of the equation (None without replicas); and the constants fitted without the
    last part (m,) (None where that fit failed)."""
    n_fit = int(round(len(x) * (1 - HELD_OUT)))
    part = _Batch(system, params, x[:n_fit], dt, integrator, substeps)
    if n_fit < part.nc + 2 * part.p:
        return None, None, None
    paths = x[None] if replicas is None or not len(replicas) else np.concatenate([x[None], replicas])
    theta = part.gauss_newton(np.repeat(centre, len(paths), axis=0), paths[:, :n_fit], CENTRE_ITERATIONS // 2)
    whole = _Batch(system, params, x, dt, integrator, substeps)
    fitted = whole.roll(centre)[0]
    miss = (whole.roll(theta) - paths)[:, n_fit:] * whole.weight
    follow = (fitted[None] - paths)[:, n_fit:] * whole.weight
    num = np.sqrt(np.mean(miss.reshape(len(paths), -1) ** 2, axis=1))
    den = np.sqrt(np.mean(follow.reshape(len(paths), -1) ** 2, axis=1))
    ok = np.all(np.isfinite(theta), axis=1) & np.isfinite(num) & (den > 0)
    ratio = np.where(ok, num / np.where(den > 0, den, 1.0), np.nan)
    null = ratio[1:][np.isfinite(ratio[1:])]
    return ((float(ratio[0]) if ok[0] else None),
            (float(null.max()) if len(null) >= len(paths[1:]) // 2 and len(null) else None),
            (theta[0, :part.m] if ok[0] else None))


def combine(value: float, boot: Bootstrap | None, name: str, *, rate_std: float = 0.0, relative: float = 0.0,
            restarts: float = 0.0, gap: float = 0.0, encoder: bool = False, scale_std: float = 0.0,
            rival: float = 0.0, one_way: bool = False, floor: float = ENCODER_FLOOR,
            level: float = LEVEL) -> Interval | None:
    """One constant's interval about `value` from the bootstrap's shares and the caller's:
    rate_std (relative std of the frame rate), scale_std (relative std of the measurement's
    scale: an angle's pivot), relative (a relative std from elsewhere: the calibration), restarts (the kept restarts' std, widened here), encoder (add the bends'
    share: a learned latent), gap (a difference between two estimates of the same constant,
    added as a bias) and rival (the distance to the farthest restart left out that tells the
    frames apart as well, selection.rivals: the clip cannot choose between them, so the interval
    reaches it); one_way: a learned latent that runs one way, whose bends are ONE_WAY_BEND; floor:
    the least the bends' share is, relative to the value (ENCODER_FLOOR; a light reading's own).
    None without a bootstrap."""
    from statistics import NormalDist
    if boot is None or not math.isfinite(boot.std.get(name, math.nan)):
        return None
    z = NormalDist().inv_cdf(0.5 + level / 2)
    scale = abs(value) / max(abs(boot.values[name]), 1e-300) if boot.values[name] else 1.0
    timing = abs(boot.timing.get(name, 0.0)) * scale * rate_std
    measure = abs(boot.scaling.get(name, 0.0)) * scale * scale_std
    shares = {"residuals": boot.std[name] * scale * boot.quantile / z,  # as a normal std with the t's width
              "timing": timing if math.isfinite(timing) else 0.0,
              "scale": measure if math.isfinite(measure) else 0.0,
              "geometry": boot.geometry.get(name, 0.0) * scale,
              "calibration": abs(value) * relative,
              "restarts": RESTART_WIDEN * restarts,
              "encoder": math.hypot(boot.bend.get(name, 0.0) * scale * (ONE_WAY_BEND / BEND if one_way else 1.0),
                                    floor * abs(value)) if encoder else 0.0}
    half = math.hypot(z * math.sqrt(sum(s * s for s in shares.values())), gap, rival)
    shares["gap"] = abs(gap)
    shares["rivals"] = abs(rival)
    return Interval(value - half, value + half, value, shares)


def result_intervals(result, system, params: Mapping, *, rate_std: float = 0.0,
                     calibration: Mapping[str, float] | None = None,
                     seed: int = 0) -> tuple[dict[str, Interval], Bootstrap | None]:
    """Every constant's interval for a FitResult, about its reported value: the bootstrap of the
    path the estimate follows (result.meta["trajectory"]["measured"] where the fit recorded a
    measured path, else the best run's latent read as the equation's state through its gauge),
    from the best run's constants; rate_std: the frame rate's relative std; calibration:
    {name: relative std} a calibration adds. The restarts' spread is added for every constant
    whose value is their mean, and the gap between the reported value (in the path's units) and
    the one trajectory's. ({}, None) where no interval can be made."""
    best = next((r for r in result.runs if r.index == result.best), None)
    if best is None or not best.final or result.meta.get("interrupted"):
        return {}, None
    from .observe.angle import pivot_moves

    x = _path(result, best)
    settings = result.settings
    # a path that can bend unseen: a learned latent, or a light read linearly (observe.base.can_bend)
    learned = bool(result.meta.get("bends", not result.meta.get("measured")))
    floor = result.meta.get("bend_floor") or ENCODER_FLOOR
    recorded = result.meta.get("trajectory") if isinstance(result.meta.get("trajectory"), Mapping) else {}
    frames, pieces = recorded.get("frames"), recorded.get("pieces")
    # an angle's pivot moved: the path of one stretch read again (the pieces' frames are not one span)
    moves = pivot_moves(x, result.meta.get("measurement"), tuple(frames)) \
        if frames and not pieces and x.shape[1] == 1 else []
    start, fixed = best.final, _gauge_fixed(result, frames)
    if fixed:  # every constant is the fit of the calibrated path: that path is what limits them
        calibrated = result.calibration
        x = np.asarray(calibrated["latent"], dtype=float)[frames[0]: frames[1]]
        start = {n: float(c["refit"]) for n, c in calibrated["constants"].items()}
        # a pivot's moves, read in the path's units, are changes the map scales as it scales the path
        maps = calibrated.get("maps") or {}
        scale = np.array([float((maps.get(s) or {}).get("a", 1.0)) for s in result.states])
        moves = [m * scale[: m.shape[1]] for m in moves]
    boot = bootstrap(system, params, x, result.dt, start, seed=seed, learned=learned, moves=moves,
                     integrator=str(settings.get("integrator", "rk4")), substeps=int(settings.get("substeps", 1)),
                     pieces=pieces, scatter=recorded.get("scatter") if pieces else None)
    out: dict[str, Interval] = {}
    own = set(result.meta.get("own_units", ()))
    # an angle's pivot moved by its uncertainty carries its scale too: the scale share is for what has no moves
    # (and where the calibration sets the path's scale, the measurement's own scale says nothing)
    scale_std = 0.0 if moves or fixed else float((result.meta.get("measurement") or {}).get("scale_error") or 0.0)
    scale_std = scale_std if math.isfinite(scale_std) else 0.0
    for name, est in result.parameters.items():
        if boot is None or name not in boot.values:
            continue
        path_value = est.latent_value if est.calibrated and est.latent_value is not None and not fixed else est.value
        ratio = est.value / path_value if path_value else 1.0
        gap = (path_value - boot.values[name]) * ratio
        restarts = est.std if est.n_runs > 1 and name not in own else 0.0
        rival = 0.0 if fixed else \
            max((abs(r.value(name) - path_value) for r in rivals(result, name)), default=0.0) * ratio
        iv = combine(est.value, boot, name, rate_std=rate_std, relative=(calibration or {}).get(name, 0.0),
                     restarts=restarts, gap=gap, encoder=learned, scale_std=scale_std, rival=rival, floor=floor,
                     one_way=learned and bool(result.checks.get("one_way")) and settings.get("encoder") != "linear")
        if iv is not None:
            out[name] = _light_curve(iv, boot, name, result.checks.get("light_curve"))
    return out, boot


def _gauge_fixed(result, frames) -> bool:
    """Whether every constant is the fit of the calibrated path (fitode.calibrate._fixes_zero: a
    measured path whose zero the calibration sets), so that the bootstrap resamples that path
    about that fit: the path's own gauge, with its zero free, let a slow drain's k trade against
    the zero (+-44% where the calibrated path gives +-1.7%)."""
    calibrated = result.calibration or {}
    fixed = set(calibrated.get("gauge_fixed") or ())
    return bool(frames) and bool(fixed) and fixed == set(result.parameters) and calibrated.get("latent") is not None


def _light_curve(iv: Interval, boot: Bootstrap, name: str, curve: Mapping | None) -> Interval:
    """iv reaching down to value / CURVE_POWER where the frames could not tell the light curve and
    the constant is a rate (it scales as 1/time: the frame rate's sensitivity near -1; a curve
    bends an oscillation's envelope, not its period); else iv."""
    along = boot.values.get(name) or 0.0
    if not curve or curve.get("told", True) or not iv.value > 0 or not along > 0 \
            or not -1.5 < boot.timing.get(name, 0.0) / along < -0.5:  # a frequency squared keeps its value
        return iv
    low = min(iv.low, iv.value / CURVE_POWER)
    return Interval(low, iv.high, iv.value, {**iv.shares, "light curve": iv.value - low})


def _path(result, best) -> np.ndarray:
    """The path (T_train, k) the estimate follows, in the equation's state units."""
    recorded = result.meta.get("trajectory")
    if isinstance(recorded, Mapping) and recorded.get("measured") is not None:
        return np.asarray(recorded["measured"], dtype=float)[: result.train_frames]
    z = np.asarray(result.latent, dtype=float)[: result.train_frames]
    s = np.array([best.gauge.get(st, {}).get("scale", 1.0) for st in result.states])
    b = np.array([best.gauge.get(st, {}).get("offset", 0.0) for st in result.states])
    return z * s + b
