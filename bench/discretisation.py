"""Discretisation study: how much each integrator and initial-state formula biases the constants.

Tables 1 and 2 are both in float64 on exact (noise-free) trajectories:

1. accuracy: every integrator, with 1 and 4 sub-steps, rolled out with the true constants from
   the true initial state at dt = 0.1 for 100 frames, against a closed form or scipy's
   solve_ivp (DOP853, rtol 1e-10, atol 1e-12). Error = max |x - x_ref| / max |x_ref| over all
   frames and states.
2. bias: the paper's damped oscillator x'' = -g0 x - g1 x' (omega = 2, zeta = 0.04, so
   g0 = 4.0016, g1 = 0.08) sampled at dt = 0.2 (omega*dt = 0.4). g0 and g1 (and, for
   init=learnable, every window's initial velocity) are fitted by least squares (L-BFGS to
   convergence) to the exact trajectory through the PhysicsBlock, windows of 20 frames at every
   start, loss on frames n_context.. as the trainer does. "official one-step" is the paper's
   code: each frame predicted from the two frames before it (windows of 3 frames, init=backward,
   symplectic).
3. noise: the fit of table 2 for RK4 with Gaussian noise (0.01, 0.03) on the trajectory, 3 seeds.
4. speed: CPU time of a forward + backward pass in the trainer's shape.

    python bench/discretisation.py            # prints the tables, writes bench/out/discretisation.json
    python bench/discretisation.py --quick    # fewer configurations
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import torch
from scipy.integrate import solve_ivp

from fitode.codegen import PhysicsBlock, simulate
from fitode.eqparse import ParamSpec, parse
from fitode.jsonio import write_json

OMEGA, ZETA = 2.0, 0.04
G0, G1 = OMEGA ** 2 + ZETA ** 2, 2 * ZETA


def _damped(t):
    return np.exp(-ZETA * t) * np.cos(OMEGA * t)


# name, equation, constants, y0, reference(t) -> (n, dim) or None for solve_ivp, rhs for solve_ivp
def accuracy_cases():
    g = 9.80665
    return [
        ("damped oscillator", "x'' = -g0*x - g1*x'", {"g0": G0, "g1": G1}, {"x": [1.0, -ZETA]},
         lambda t: _damped(t)[:, None], None),
        ("exponential decay", "x' = -k*x", {"k": 0.5}, {"x": 2.0},
         lambda t: (2.0 * np.exp(-0.5 * t))[:, None], None),
        ("torricelli", "h' = -k*sqrt(h)", {"k": 0.1}, {"h": 1.0},
         lambda t: ((1.0 - 0.1 * t / 2) ** 2)[:, None], None),
        ("free fall", "y'' = -g", {}, {"y": [10.0, 1.0]},
         lambda t: (10.0 + t - g * t ** 2 / 2)[:, None], None),
        ("pendulum 115 deg", "theta'' = -g/L*sin(theta) - zeta*theta'", {"L": 2.0, "zeta": 0.1},
         {"theta": [2.0, 0.0]}, None,
         lambda t, y: [y[1], -g / 2.0 * np.sin(y[0]) - 0.1 * y[1]]),
        ("lotka-volterra", "u' = a*u - b*u*v; v' = -c*v + d*u*v", {"a": 1.1, "b": 0.4, "c": 0.4, "d": 0.1},
         {"u": 10.0, "v": 5.0}, None,
         lambda t, y: [1.1 * y[0] - 0.4 * y[0] * y[1], -0.4 * y[1] + 0.1 * y[0] * y[1]]),
    ]


def reference(case, n_frames: int, dt: float) -> np.ndarray:
    _, _, _, y0, closed, rhs = case
    t = np.arange(n_frames) * dt
    if closed is not None:
        return closed(t)
    flat = [v for vals in y0.values() for v in (vals if isinstance(vals, list) else [vals])]
    sol = solve_ivp(rhs, (0, t[-1]), flat, method="DOP853", t_eval=t, rtol=1e-10, atol=1e-12)
    if len(y0) == 1:  # one second-order state: its value is the first component
        return sol.y[0][:, None]
    return sol.y.T


def accuracy_table(n_frames: int = 100, dt: float = 0.1) -> list[dict]:
    rows = []
    for case in accuracy_cases():
        name, eq, consts, y0 = case[:4]
        system = parse(eq)
        ref = reference(case, n_frames, dt)
        row = {"system": name}
        for integ in ("euler", "symplectic", "rk4"):
            for sub in (1, 4):
                x = simulate(system, consts, y0, n_frames, dt, integ, sub).numpy()
                row[f"{integ}/{sub}"] = float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))
        rows.append(row)
    return rows


def fit_constants(integrator: str, substeps: int, init: str, context: int | None, *, n_total: int = 200,
                  window: int = 20, dt: float = 0.2, max_iter: int = 500, noise: float = 0.0,
                  seed: int = 0) -> dict:
    """Least-squares g0, g1 (and learnable initial velocities) on the damped trajectory (+ noise)."""
    z = torch.tensor(_damped(np.arange(n_total) * dt), dtype=torch.float64)[:, None]
    if noise:
        z = z + noise * torch.randn(z.shape, generator=torch.Generator().manual_seed(seed), dtype=z.dtype)
    starts = torch.arange(n_total - window + 1)
    windows = z[starts[:, None] + torch.arange(window)]  # (W, window, 1)
    system = parse("x'' = -g0*x - g1*x'")
    params = {"g0": ParamSpec(init=G0), "g1": ParamSpec(init=G1)}
    block = PhysicsBlock(system, params, integrator=integrator, substeps=substeps, init=init,
                         context=context, n_windows=len(starts), dtype=torch.float64)
    nc = block.n_context
    block(windows[:, :nc], window, dt, window_index=starts)  # initialise learnable velocities
    opt = torch.optim.LBFGS(block.parameters(), lr=1.0, max_iter=max_iter, tolerance_grad=1e-14,
                            tolerance_change=1e-16, history_size=50, line_search_fn="strong_wolfe")

    def closure():
        opt.zero_grad()
        pred = block(windows[:, :nc], window, dt, window_index=starts)
        loss = torch.mean((pred[:, nc:] - windows[:, nc:]) ** 2)
        loss.backward()
        return loss

    for _ in range(3):
        loss = opt.step(closure).detach()
    c = {k: v.item() for k, v in block.constants().items()}
    return {"g0": c["g0"], "g1": c["g1"], "g0_bias_pct": 100 * (c["g0"] / G0 - 1),
            "g1_bias_pct": 100 * (c["g1"] / G1 - 1), "rmse": math.sqrt(loss.item()), "n_context": nc}


def bias_table(quick: bool = False) -> list[dict]:
    configs = [("official one-step", "symplectic", 1, "backward", None, 3)]
    inits = [("backward", None), ("difference", 3), ("difference", 5), ("learnable", None)]
    if quick:
        inits = [("backward", None), ("difference", 5), ("learnable", None)]
    for integ in ("euler", "symplectic", "rk4"):
        for sub in (1, 4):
            for init, ctx in inits:
                configs.append((None, integ, sub, init, ctx, 20))
    rows = []
    for label, integ, sub, init, ctx, window in configs:
        t0 = time.perf_counter()
        r = fit_constants(integ, sub, init, ctx, window=window)
        init_label = init if ctx is None else f"{init}({ctx})"
        rows.append({"config": label or f"{integ} x{sub}", "integrator": integ, "substeps": sub,
                     "init": init_label, "window": window, **r, "seconds": time.perf_counter() - t0})
    return rows


def noise_table(noises=(0.01, 0.03), seeds=(0, 1, 2)) -> list[dict]:
    """Mean and spread of the fitted constants when the trajectory carries Gaussian noise."""
    rows = []
    for noise in noises:
        for integ, sub in (("rk4", 1), ("rk4", 4)):
            for init, ctx in (("difference", 3), ("difference", 5), ("learnable", None)):
                fits = [fit_constants(integ, sub, init, ctx, noise=noise, seed=s) for s in seeds]
                g0 = np.array([f["g0"] for f in fits])
                g1 = np.array([f["g1"] for f in fits])
                rows.append({"noise": noise, "config": f"{integ} x{sub}",
                             "init": init if ctx is None else f"{init}({ctx})",
                             "g0_mean_bias_pct": float(100 * (g0.mean() / G0 - 1)), "g0_std": float(g0.std()),
                             "g1_mean_bias_pct": float(100 * (g1.mean() / G1 - 1)), "g1_std": float(g1.std()),
                             "seeds": len(seeds)})
    return rows


def speed_table(n_windows: int = 181, window: int = 20, reps: int = 20) -> list[dict]:
    """CPU time of one forward + backward through the block (float32, 1 thread), the trainer's shape."""
    system = parse("x'' = -g0*x - g1*x'")
    rows = []
    for integ, sub, init in (("symplectic", 1, "backward"), ("euler", 1, "backward"), ("rk4", 1, "difference"),
                             ("rk4", 2, "difference"), ("rk4", 4, "difference")):
        block = PhysicsBlock(system, integrator=integ, substeps=sub, init=init)
        z = torch.randn(n_windows, block.n_context, 1, requires_grad=True,
                        generator=torch.Generator().manual_seed(0))
        for _ in range(3):
            block(z, window, 0.2).sum().backward()
        t0 = time.process_time()
        for _ in range(reps):
            block(z, window, 0.2).sum().backward()
        rows.append({"integrator": integ, "substeps": sub, "init": init,
                     "ms_per_forward_backward": (time.process_time() - t0) / reps * 1e3})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="bench/out/discretisation.json")
    args = ap.parse_args()
    torch.set_num_threads(1)

    acc = accuracy_table()
    cols = [f"{i}/{s}" for i in ("euler", "symplectic", "rk4") for s in (1, 4)]
    print("Relative max error vs closed form / solve_ivp, dt = 0.1, 100 frames (integrator/substeps)")
    print(f"{'system':<20}" + "".join(f"{c:>14}" for c in cols))
    for r in acc:
        print(f"{r['system']:<20}" + "".join(f"{r[c]:>14.2e}" for c in cols))

    bias = bias_table(args.quick)
    print(f"\nDamped oscillator omega*dt = {OMEGA * 0.2:.1f}: least-squares g0 (true {G0}), g1 (true {G1}) "
          f"on the exact trajectory, 200 frames")
    print(f"{'config':<20}{'init':<15}{'ctx':>4}{'win':>5}{'g0':>10}{'bias %':>9}{'g1':>10}{'bias %':>9}{'rmse':>10}")
    for r in bias:
        print(f"{r['config']:<20}{r['init']:<15}{r['n_context']:>4}{r['window']:>5}{r['g0']:>10.4f}"
              f"{r['g0_bias_pct']:>9.2f}{r['g1']:>10.4f}{r['g1_bias_pct']:>9.2f}{r['rmse']:>10.2e}")

    # The paper's scheme is the linear recurrence z+ = a z + b z-, a = 2 - dt^2 g0 - dt g1, b = dt g1 - 1;
    # the exact trajectory obeys one with a = 2 exp(-zeta dt) cos(omega dt), b = -exp(-2 zeta dt).
    dt = 0.2
    a, b = 2 * math.exp(-ZETA * dt) * math.cos(OMEGA * dt), -math.exp(-2 * ZETA * dt)
    g0_floor, g1_floor = (1 - a - b) / dt ** 2, (1 + b) / dt
    leapfrog = 2 * (1 - math.cos(OMEGA * dt)) / dt ** 2
    print(f"analytic floor of the paper's scheme: g0 = {g0_floor:.4f} ({100 * (g0_floor / G0 - 1):+.2f} %), "
          f"g1 = {g1_floor:.4f} ({100 * (g1_floor / G1 - 1):+.2f} %); undamped leapfrog frequency alone: "
          f"g0 = {leapfrog:.4f} ({100 * (leapfrog / OMEGA ** 2 - 1):+.2f} %)")

    noisy = [] if args.quick else noise_table()
    if noisy:
        print("\nSame fit with Gaussian noise on the trajectory (amplitude 1), mean over 3 seeds")
        print(f"{'noise':>6}  {'config':<10}{'init':<15}{'g0 bias %':>10}{'g0 std':>9}{'g1 bias %':>10}{'g1 std':>9}")
        for r in noisy:
            print(f"{r['noise']:>6}  {r['config']:<10}{r['init']:<15}{r['g0_mean_bias_pct']:>10.2f}"
                  f"{r['g0_std']:>9.4f}{r['g1_mean_bias_pct']:>10.2f}{r['g1_std']:>9.4f}")

    speed = speed_table()
    print("\nCPU time per forward+backward, 181 windows x 20 frames, float32, 1 thread")
    for r in speed:
        print(f"  {r['integrator']:<11} x{r['substeps']}  {r['init']:<11} {r['ms_per_forward_backward']:7.2f} ms")

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json({"accuracy": acc, "bias": bias, "noise": noisy, "speed": speed, "g0_true": G0, "g1_true": G1}, out, indent=2)
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
