"""Does the equation hold over the whole clip? One trajectory against the measured latent.

A measured latent (a centroid, a radius: observe.py's geometric models) is what the camera saw,
whatever the equation says, so an equation that does not describe the motion does not show as a
bent latent: the windows' fit settles on constants that average over the clip, every restart
agrees, and the number looks trusted. The real slow-motion ball drop is the case in point: in
its last fifth the ball falls visibly behind the parabola of its first frames (a light ball in
air; a camera that looks at the wall at an angle), and the whole clip gives g = 8.0 m/s^2
(-18%) with three restarts agreeing.

Short windows cannot see it: over 20 frames the misfit hides under the noise of the velocity
each window starts from, and a miss measured against the noise depends on how the noise of
neighbouring frames hangs together (motion blur, the codec). The constants say it plainly: the
clip is cut in two and each half is fitted as one trajectory of the equation (its starting
state and constants both free, from the fit's values; L-BFGS), with a standard error. Where a
constant differs between the halves by more than SIGMAS standard errors and more than HALF_TOL
of its value, one set of constants does not hold over the clip, and the verdict says so.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from .verdict import Finding

HALF_TOL = 0.05
SIGMAS = 3.0
ITERATIONS = 100
PERSPECTIVE = "perspective"  # the bend's c, among trajectory_fit's values when bend=True
MISFIT = "misfit"  # the RMS residual in units of the (bent) state's spread, among trajectory_fit's values
POLE_MARGIN = 0.9
BEND_MIN = 0.01  # a perspective that bends the path's ends by less changes nothing worth a second training


def whole_clip_check(system, params: Mapping, state: np.ndarray, dt: float, start: Mapping[str, float],
                     config) -> tuple[Finding | None, dict[str, list[float]]]:
    """The finding (None where the halves agree, or a half could not be fitted) and the numbers
    behind it: each constant fitted as one trajectory on the first and on the second half of
    state (T, d), with its standard error."""
    x = np.asarray(state, dtype=np.float64)
    half = x.shape[0] // 2
    if half < 8 or not np.all(np.isfinite(x)):
        return None, {}
    halves = [trajectory_fit(system, params, part, dt, start, config) for part in (x[:half], x[half:])]
    if any(h is None for h in halves):
        return None, {}
    numbers = {n: [halves[0][0][n], halves[0][1][n], halves[1][0][n], halves[1][1][n]] for n in system.learnable}
    apart = []
    for n, (a, se_a, b, se_b) in numbers.items():
        gap = abs(a - b)
        if gap > HALF_TOL * max(abs(float(start[n])), 1e-12) and gap > SIGMAS * math.hypot(se_a, se_b):
            apart.append(f"{n} {a:.4g} +- {se_a:.2g} on the first half and {b:.4g} +- {se_b:.2g} on the second")
    if not apart:
        return None, numbers
    return Finding("ambiguous", "one set of constants does not hold over the whole clip: fitted as one trajectory, "
                   + "; ".join(apart) + " (in the fit's own units): drag, a camera at an angle to the motion or a "
                   "missing term changes the motion; fit only the part where the equation holds (--start/--end) "
                   "or extend the equation"), numbers


def trajectory_fit(system, params: Mapping, x: np.ndarray, dt: float, start: Mapping[str, float],
                   config, bend: bool = False) -> tuple[dict[str, float], dict[str, float]] | None:
    """The constants of the single trajectory of the equation that best follows x (T, d), and
    their standard errors: its starting state and its constants both free, from x's first frames
    and `start` (L-BFGS). The errors come from the Jacobian (least squares' covariance), widened
    for residuals that hang together from frame to frame (by (1 + r) / (1 - r) for a lag-one
    correlation r). None where it cannot be fitted (it leaves the equation's domain).

    bend: x is first read through a perspective (one-dimensional homography) about its middle
    m, x -> m + (x - m) / (1 + c (x - m)), with c fitted too (kept so that the pole stays outside
    the measured range) and returned as the constant PERSPECTIVE, in 1 / x's units; the misfit is
    then measured against the bent x's own spread, so that a bend cannot win by shrinking x."""
    import torch
    from torch.func import functional_call

    from fitode.codegen import PhysicsBlock
    from fitode.errors import FitodeError

    xt = torch.as_tensor(x)
    middle = xt.mean(dim=0)
    reach = 1.0 / (xt - middle).abs().max().clamp_min(1e-24)  # the largest |c| that keeps the pole outside

    def bent(a):
        if not bend:
            return xt
        c = POLE_MARGIN * reach * torch.tanh(a)
        return middle + (xt - middle) / (1 + c * (xt - middle))
    try:
        block = PhysicsBlock(system, params, integrator=config.integrator, substeps=config.substeps).double()
        block.set_constants(dict(start))
        context = xt[: block.n_context].clone().requires_grad_(True)
        named = [(k, p) for k, p in block.named_parameters() if p.requires_grad]
        if bend:
            named.append((PERSPECTIVE, torch.zeros((), dtype=xt.dtype, requires_grad=True)))
        models = dict(block.named_parameters())

        def misfit(swapped, ctx):
            target = bent(swapped[PERSPECTIVE] if bend else None)
            root = (1.0 / target.var(dim=0).clamp_min(1e-24)).sqrt()  # every state counts equally, whatever its units
            own = {k: v for k, v in swapped.items() if k in models}
            out = functional_call(block, own, (ctx[None], x.shape[0], dt))[0]
            return ((out - target) * root).flatten()
        opt = torch.optim.LBFGS([p for _, p in named] + [context], lr=0.5, max_iter=ITERATIONS,
                                line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad(set_to_none=True)
            value = torch.mean(misfit(dict(named), context) ** 2)
            value.backward()
            return value
        opt.step(closure)
        sizes = [p.numel() for _, p in named] + [context.numel()]
        flat = torch.cat([p.detach().flatten() for _, p in named] + [context.detach().flatten()])

        def residual(v):
            parts = list(torch.split(v, sizes))
            swapped = {k: part.view_as(p) for (k, p), part in zip(named, parts[:-1])}
            return misfit(swapped, parts[-1].view_as(context))
        r = residual(flat).detach()
        jac = torch.autograd.functional.jacobian(residual, flat, vectorize=True, strategy="forward-mode")
        dof = max(r.numel() - flat.numel(), 1)
        lag = float((r[1:] @ r[:-1]) / (r @ r).clamp_min(1e-300)) if r.numel() > 2 else 0.0
        lag = min(max(lag, 0.0), 0.95)
        cov = torch.linalg.pinv(jac.T @ jac) * float(r @ r) / dof * (1 + lag) / (1 - lag)
        outputs = dict(block.constants())
        if bend:
            outputs[PERSPECTIVE] = POLE_MARGIN * reach * torch.tanh(named[-1][1])
        values, errors = {}, {}
        for name, value in outputs.items():
            grads = torch.autograd.grad(value, [p for _, p in named], allow_unused=True)
            g = torch.cat([(gr if gr is not None else torch.zeros_like(p)).flatten()
                           for gr, (_, p) in zip(grads, named)] + [torch.zeros(context.numel(), dtype=flat.dtype)])
            values[name] = float(value.detach())
            errors[name] = float((g @ cov @ g).clamp_min(0).sqrt())
        values[MISFIT] = float((r @ r) / r.numel()) ** 0.5
    except (FitodeError, RuntimeError, FloatingPointError):
        return None
    finite = np.all(np.isfinite(list(values.values()) + list(errors.values())))
    return (values, errors) if finite else None


def perspective_check(system, params: Mapping, state: np.ndarray, dt: float, start: Mapping[str, float],
                      config, straight: tuple[dict[str, float], dict[str, float]] | None = None) -> dict | None:
    """Is the measured path read through a perspective? A camera that looks at a line of motion
    at an angle sees equal steps along it as unequal ones, nearer larger, which is a
    one-dimensional homography of the position: a fall filmed from below the ceiling looks as if
    it slowed down (the real ball drop: g 16 on the first half of the clip against 11 on the
    second, in latent units). The single trajectory of the equation is fitted to the whole path
    read straight and read through a bend (trajectory_fit with bend=True); the bend is to be
    applied where it is SIGMAS standard errors from zero, bends the ends of the path by at least
    BEND_MIN, and fits better. A bend cannot make a parabola of another parabola (nor any law
    of itself with other constants), so the bend that fits is the camera's, not a re-reading
    of the dynamics: its one number is decided by the whole clip.

    straight: trajectory_fit's result for the same state and start, where the caller has it.
    None for a latent of more than one dimension or a fit that fails; otherwise the numbers:
    c and its error, the middle m the bend is about (x -> m + (x - m) / (1 + c (x - m))), the
    bend at the path's ends, the misfit read straight and bent, and whether to apply it."""
    x = np.asarray(state, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 1 or x.shape[0] < 16 or not np.all(np.isfinite(x)):
        return None
    if straight is None:
        straight = trajectory_fit(system, params, x, dt, start, config)
    bent = trajectory_fit(system, params, x, dt, start, config, bend=True)
    if straight is None or bent is None:
        return None
    c, se = bent[0][PERSPECTIVE], bent[1][PERSPECTIVE]
    middle = float(x.mean())
    ends = abs(c) * float(np.abs(x - middle).max())
    misfit = [straight[0][MISFIT], bent[0][MISFIT]]
    apply = abs(c) > SIGMAS * se and ends >= BEND_MIN and misfit[1] < misfit[0]
    return {"c": c, "se": se, "middle": middle, "bend_at_ends": ends, "misfit": misfit, "apply": bool(apply),
            "constants": {n: [straight[0][n], bent[0][n]] for n in system.learnable}}


def unbend(x: np.ndarray, c: float, middle: float) -> np.ndarray | None:
    """x read through the perspective bend about middle; None where a frame lies beyond the
    bend's pole (a held-out frame far outside the range the bend was fitted on)."""
    d = np.asarray(x, dtype=np.float64) - middle
    denominator = 1.0 + c * d
    if np.any(denominator <= 0.05):
        return None
    return middle + d / denominator


def one_trajectory_check(system, params: Mapping, state: np.ndarray, dt: float, values: Mapping[str, float],
                         config, fitted: tuple[dict[str, float], dict[str, float]] | None = None,
                         ) -> tuple[list[Finding], dict[str, list[float]]]:
    """Do the windows' constants agree with one trajectory of the equation over the whole clip?
    Short windows see little of what acts slowly: a pendulum's light damping takes off a few
    percent of the swing per window, and the windows' damping can land anywhere near it (the real
    bob clip: zeta 0.0166 from the windows, 0.0059 from one trajectory over its 31 s, 0.0056
    from a colour tracker's damped-sine fit). The whole state (T, d) is fitted as one trajectory,
    starting from the windows' constants; each constant farther from it than SIGMAS standard
    errors and HALF_TOL of its value gets an ambiguous finding of its own, which names the
    trajectory's value. fitted: trajectory_fit's result for the same state and start, where the
    caller has it. Returns the findings and each constant's [trajectory value, its error]."""
    x = np.asarray(state, dtype=np.float64)
    if x.shape[0] < 16 or not np.all(np.isfinite(x)):
        return [], {}
    if fitted is None:
        fitted = trajectory_fit(system, params, x, dt, values, config)
    if fitted is None:
        return [], {}
    found, numbers = [], {}
    for n in system.learnable:
        whole, se = fitted[0][n], fitted[1][n]
        numbers[n] = [whole, se]
        gap = abs(float(values[n]) - whole)
        if gap > HALF_TOL * max(abs(whole), 1e-12) and gap > SIGMAS * se:
            found.append(Finding("ambiguous", f"the windows give {n} = {float(values[n]):.4g} but one trajectory of the "
                                 f"equation over the whole clip gives {whole:.4g} +- {se:.2g} (in the fit's own units): "
                                 "the windows see too little of what acts slowly (light damping over a few periods); "
                                 "the whole-clip value is the better one", (n,)))
    return found, numbers
