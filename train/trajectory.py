"""One trajectory fitter: the equation's constants (and starting state) that best follow a fixed
trajectory, with standard errors.

A fixed trajectory x (T, k), one column per state (a measured path, a calibrated latent, a frozen
readout of the frames), is fitted by the physics block in float64 with L-BFGS and a strong-Wolfe
line search, or Levenberg-Marquardt (solver "lm"). Two ways to cut it:

- whole (windows=None): x is one trajectory of the equation; its starting frames and the
  constants are both free. What acts slowly (light damping, drag) shows over the whole clip.
- windows (windows=N): x is cut into windows of N frames, each rolled out from its own first
  frames as the training does, with the constants shared (multiple shooting). This is the
  training's own question asked of a fixed latent, so a window fit on a latent and on its affine
  image give constants that differ only by the map.

Every state counts equally, whatever its units: each column's residual is divided by that
column's spread. The errors come from the Jacobian (least squares' covariance, the Jacobian taken
forward-mode), widened for residuals that hang together from frame to frame (by (1 + r) / (1 - r)
for a lag-one correlation r; in windows, the error of each window's starting state makes its
residuals hang together, so their errors are wide).

segments (whole mode only): the one trajectory is rolled out as consecutive pieces of that many
frames, each from starting frames of its own, its first frames rolled out tied to the end of the
piece before by a stiff residual (multiple shooting): the same trajectory at the minimum, but each rollout is short, so a
clip of thousands of frames costs what a few dozen do (the rollout is one Python step per frame).
A whole trajectory without segments is one segment. solver "lm" (Levenberg-Marquardt on the
Jacobian by forward differences) takes a few dozen steps where L-BFGS takes hundreds; it suits the
many starting frames of segments. It is bounded (ITERATIONS steps, TRIALS_PER_STEP trial rollouts
a step in all) and says when it stopped at its bound (converged False; steps and rollouts counted).

Where no gradient is asked for (Levenberg-Marquardt, the errors) the rollout is NumPy code
generated from the same equation (codegen.compile_numpy, PhysicsBlock.rollout_numpy), and every
column of the Jacobian the block can roll out (each constant, the segments' starting frames) is
one copy of a single batched rollout; L-BFGS differentiates the torch rollout.

bend: x is first read through a perspective (one-dimensional homography) about its middle m,
x -> m + (x - m) / (1 + c (x - m)), with c fitted too (kept so that the pole stays outside the
measured range) and returned as the constant PERSPECTIVE, in 1 / x's units; the misfit is then
measured against the bent x's own spread, so that a bend cannot win by shrinking x.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

ITERATIONS = 100
MAX_WINDOWS = 128  # windows beyond this are thinned to evenly spaced ones: more say little new
PERSPECTIVE = "perspective"  # the bend's c, among the values when bend=True
POLE_MARGIN = 0.9
JOIN_WEIGHT = 300.0  # a jump between two segments costs as much as JOIN_WEIGHT**2 frames' misfit of its size
SOLVERS = ("lbfgs", "lm")
TRIALS = 24  # dampings (each ten times the last) tried within one Levenberg-Marquardt step
TRIALS_PER_STEP = 3  # trial rollouts per step on average, in all: the bound on a fit's work
SEGMENT = 60  # frames per shooting segment of a long path (long_options)


@dataclass
class TrajectoryFit:
    """What fit_trajectory found."""

    values: dict[str, float]  # the learnable constants (and PERSPECTIVE with bend)
    errors: dict[str, float]  # their standard errors
    misfit: float  # RMS residual in units of each (bent) state's spread
    residuals: np.ndarray  # (T, k) whole; (windows, N - context, k) windows; in x's units
    converged: bool  # the solver stopped on its tolerances within its bounds
    windows: int | None = None  # the window length, None for the whole trajectory
    start: np.ndarray | None = None  # (context, k) the fitted starting frames, whole mode only
    gauge: dict[str, dict[str, float]] | None = None  # state -> scale, offset: the state is scale * x + offset
    steps: int = 0  # the solver's steps (Levenberg-Marquardt: Jacobians; L-BFGS: iterations)
    rollouts: int = 0  # Levenberg-Marquardt's trial rollouts (its bound: TRIALS_PER_STEP * iterations)


def fit_trajectory(system, params: Mapping, x: np.ndarray, dt: float, start: Mapping[str, float], *,
                   integrator: str = "rk4", substeps: int = 1, windows: int | None = None, bend: bool = False,
                   max_windows: int = MAX_WINDOWS, robust: bool = False, iterations: int = ITERATIONS,
                   gauge: Mapping | None = None, segments: int | None = None,
                   solver: str = "lbfgs", keep: np.ndarray | None = None) -> TrajectoryFit | None:
    """The constants of the equation `system` that best follow x (T, k), from `start` (see the
    module docstring for windows and bend). robust: soft-L1 instead of squares on the residuals
    (a second pass, scaled by the first pass's robust spread), for a trajectory with outlying
    frames. gauge: {state: fitode.eqparse.gauge.StateGauge} where x is a latent whose scale or
    offset the equation fixes (the trainer's gauge: the state is s*x + b per column): the learned
    s and b are fitted too (starting as the trainer's do) and the misfit is measured in x's units.
    keep (whole mode only): a boolean per frame; the frames it leaves out count for nothing, yet
    the one trajectory runs through them, and the residuals cover them too (what it predicts
    there: a held-out block of a cross-validation, fitode.train.crossval).
    None where it cannot be fitted (it leaves the equation's domain, too few frames)."""
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {', '.join(SOLVERS)}")
    with _one_thread():
        return _fit(system, params, x, dt, start, integrator, substeps, windows, bend, max_windows, robust,
                    iterations, gauge, segments, solver, keep)


def _one_thread():
    """torch on one intra-op thread while a trajectory is fitted: its tensors hold a few hundred
    numbers, and two threads on a busy machine made the fit of a 39-frame path 3.7x slower."""
    from .threads import torch_threads
    return torch_threads(1)


def _fit(system, params, x, dt, start, integrator, substeps, windows, bend, max_windows, robust, iterations, gauge,
         segments, solver, keep) -> TrajectoryFit | None:
    import torch

    from fitode.codegen import PhysicsBlock
    from fitode.errors import FitodeError

    xt = torch.as_tensor(np.asarray(x, dtype=np.float64)).reshape(len(x), -1)
    if not bool(torch.isfinite(xt).all()):
        return None
    try:
        block = PhysicsBlock(system, params, integrator=integrator, substeps=substeps, dtype=torch.float64)
        block.set_constants({n: float(start[n]) for n in system.learnable})
        problem = _Problem(block, xt, dt, windows, bend, max_windows, gauge, segments, keep)
        named = [(k, p) for k, p in block.named_parameters() if p.requires_grad] + problem.extra
        scales = problem.scales(named)
        trials = 0
        if solver == "lm":
            converged, steps, trials = _levenberg(problem, named, scales, iterations)
        else:
            converged, steps = _minimise(lambda values: torch.mean(problem.residual(values) ** 2), named, scales,
                                         iterations)
        if robust:
            with torch.no_grad():
                r = problem.residual(dict(named)).detach()
            spread = 1.4826 * float((r - r.median()).abs().median())
            if spread > 0:
                converged, more = _minimise(lambda values: torch.mean(_soft_l1(problem.residual(values), spread)),
                                            named, scales, iterations)
                steps += more
        fit = _summary(block, problem, named, scales, converged, robust)
        if fit is not None:
            fit.steps, fit.rollouts = steps, trials
        return fit
    except (FitodeError, RuntimeError, FloatingPointError, ValueError):
        return None


def long_options(n_frames: int) -> dict:
    """Options of fit_trajectory for a path of n_frames: segments and Levenberg-Marquardt where it
    is long (the rollout is one Python step per frame: a whole trajectory of a thousand frames per
    L-BFGS step is what made a fit take minutes)."""
    return {"segments": SEGMENT, "solver": "lm"}


class _Problem:
    """The residual of one fit as a function of its free tensors, in units of each state's spread."""

    def __init__(self, block, xt, dt: float, windows: int | None, bend: bool, max_windows: int,
                 gauge: Mapping | None = None, segments: int | None = None, keep: np.ndarray | None = None):
        import torch

        from .latent_map import SCALE_START

        self.block, self.xt, self.dt, self.bend, self.windows = block, xt, float(dt), bend, windows
        self.models = dict(block.named_parameters())
        nc, T = block.n_context, xt.shape[0]
        self.middle = xt.mean(dim=0)
        self.reach = 1.0 / (xt - self.middle).abs().max().clamp_min(1e-24)  # the largest |c| with the pole outside
        self.extra = [(PERSPECTIVE, torch.zeros((), dtype=xt.dtype, requires_grad=True))] if bend else []
        plans = [gauge.get(st) for st in block.system.states] if gauge else []
        self.learn_scale = [i for i, g in enumerate(plans) if g is not None and g.scale_learned]
        self.learn_offset = [i for i, g in enumerate(plans) if g is not None and g.offset_learned]
        if self.learn_scale:  # a learned scale starts small, as the trainer's: a small swing, where sin(x) ~ x
            self.extra.append(("gauge_scale", torch.full((len(self.learn_scale),), math.log(SCALE_START),
                                                         dtype=xt.dtype, requires_grad=True)))
        if self.learn_offset:  # a state under sqrt or log starts inside its domain, half a spread above zero
            s0 = [SCALE_START if i in self.learn_scale else 1.0 for i in self.learn_offset]
            b0 = [max(0.0, float(-(s * xt[:, i]).min() + 0.5 * s * xt[:, i].std())) if plans[i].positive else 0.0
                  for s, i in zip(s0, self.learn_offset)]
            self.extra.append(("gauge_offset", torch.tensor(b0, dtype=xt.dtype, requires_grad=True)))
        self.keep = None
        if keep is not None:
            if windows is not None or len(keep) != T:
                raise ValueError("keep is one flag per frame of a whole trajectory")
            self.keep = torch.as_tensor(np.asarray(keep, dtype=np.float64))[:, None]
        if windows is None:
            if T < nc + 2:
                raise ValueError("too few frames for one trajectory")
            self.index = None
            # the whole trajectory is one segment: the same residual, and its Jacobian one batched rollout
            self.pieces = _pieces(T, nc, T if segments is None else segments)
            firsts, self.length, self.seg, self.off = self.pieces
            self.extra.append(("start", xt[firsts[:, None] + np.arange(nc)[None, :]].clone().requires_grad_(True)))
        else:
            n = min(int(windows), T)
            if n < nc + 1:
                raise ValueError("windows shorter than the block's context")
            first = np.arange(T - n + 1)
            if len(first) > max_windows:
                first = np.unique(np.round(np.linspace(0, T - n, max_windows)).astype(int))
            self.index = torch.as_tensor(first[:, None] + np.arange(n)[None, :])
            self.pieces = None

    def scales(self, named: list) -> list:
        """The size of a step in each free tensor that matters: the starting frames move on each
        state's spread, a constant on its own magnitude. L-BFGS steps in these units, so that a
        constant of 900 px/s^2 and frames of a few hundred pixels are equally easy to move."""
        import torch
        spread = self.xt.std(dim=0).clamp_min(1e-12)
        out = []
        for k, p in named:
            if k == "start":
                out.append(spread.expand_as(p).clone())
            elif k in (PERSPECTIVE, "gauge_scale"):
                out.append(torch.ones_like(p))
            elif k == "gauge_offset":
                out.append(p.detach().abs() + spread[self.learn_offset])
            else:
                out.append(p.detach().abs().clamp_min(1e-3))
        return out

    def bent(self, swapped):
        if not self.bend:
            return self.xt
        import torch
        c = POLE_MARGIN * self.reach * torch.tanh(swapped[PERSPECTIVE])
        d = self.xt - self.middle
        return self.middle + d / (1 + c * d)

    def perspective(self, swapped):
        import torch
        return POLE_MARGIN * self.reach * torch.tanh(swapped[PERSPECTIVE])

    def gauge(self, swapped):
        """(s, b), each (k,): the equation's state is s * x + b."""
        import torch
        s = torch.ones(self.xt.shape[1], dtype=self.xt.dtype)
        b = torch.zeros(self.xt.shape[1], dtype=self.xt.dtype)
        if self.learn_scale:
            s = s.index_put((torch.tensor(self.learn_scale),), swapped["gauge_scale"].exp())
        if self.learn_offset:
            b = b.index_put((torch.tensor(self.learn_offset),), swapped["gauge_offset"])
        return s, b

    def roll(self, own: dict, head, n_frames: int):
        """The block's rollout (B, n_frames, k) of the starting frames head (B, context, k) with the
        block's raw constants own (each 0-d, or (B,): one set per rollout). Through torch where a
        gradient is asked for (L-BFGS); otherwise the NumPy field, which costs a fraction of torch's
        per step (the rollout is one Python step per frame)."""
        import torch
        if torch.is_grad_enabled() and (head.requires_grad or any(v.requires_grad for v in own.values())):
            from torch.func import functional_call
            return functional_call(self.block, own, (head, n_frames, self.dt))
        from fitode.errors import NonFiniteError
        values = [v.detach().numpy() for v in self.block.values_of(own).values()]
        out = self.block.rollout_numpy(head.detach().numpy(), n_frames, self.dt, values)
        if not np.isfinite(out).all():
            raise NonFiniteError("the rollout left the equation's domain")
        return torch.from_numpy(out)

    def difference(self, swapped):
        """prediction - target, in the target's units: (T, k) whole, (W, N - context, k) windows."""
        target = self.bent(swapped)
        if self.index is None:
            return self.piecewise(swapped)[0][0] - target
        own = {k: v for k, v in swapped.items() if k in self.models}
        s, b = self.gauge(swapped)
        nc = self.block.n_context
        xw = target[self.index]
        state = self.roll(own, xw[:, :nc] * s + b, xw.shape[1])
        return (state[:, nc:] - b) / s - xw[:, nc:]

    def piecewise(self, swapped, start=None, constants: dict | None = None):
        """The segments' rollouts in x's units: the frames (C, T, k) each from its own segment, and
        the jumps (C, S - 1, context, k) between a segment's end and the frames the next one rolls out
        from its starting frames (a frame is read from the last segment that has rolled it out),
        for C sets of starting frames `start` (C, S, context, k) (default: the fitted ones, C = 1)
        and of the block's raw constants `constants` ({name: (C,)}; default: the fitted ones)."""
        own = {k: v for k, v in swapped.items() if k in self.models}
        s, b = self.gauge(swapped)
        start = swapped["start"][None] if start is None else start
        nc, k = self.block.n_context, start.shape[-1]
        if constants is not None:  # one set per copy, for each of its segments
            own = {key: v[:, None].expand(-1, start.shape[1]).reshape(-1) for key, v in constants.items()}
        head = (start * s + b).reshape(-1, nc, k)
        state = (self.roll(own, head, self.length) - b) / s
        state = state.reshape(*start.shape[:2], self.length, k)
        step = self.length - 2 * nc  # the frames between two segments' starts
        # the join compares rolled-out frames of both, past the next one's starting frames: the state
        # a rollout starts from is read from its starting frames by finite differences (a derivative
        # off by (omega dt)^2 / 6), so starting frames tied to the frames before made each segment
        # another trajectory (the paper's motion video: g1 0.067% low on an exact path)
        if start.shape[1] == 1:  # one segment, no join (a path shorter than two contexts has no frames past them)
            return state[:, self.seg, self.off], state[:, :0, :nc]
        return state[:, self.seg, self.off], state[:, :-1, step + nc:step + 2 * nc] - state[:, 1:, nc:2 * nc]

    def pieces_residual(self, swapped, start=None, constants: dict | None = None):
        """residual() for C sets of segment starts (and of the block's constants) at once: (C, rows)."""
        import torch
        root = (1.0 / self.bent(swapped).var(dim=0).clamp_min(1e-24)).sqrt()
        frames, joins = self.piecewise(swapped, start, constants)
        data = (frames - self.bent(swapped)) * root
        if self.keep is not None:
            data = data * self.keep
        return torch.cat([data.flatten(1), (JOIN_WEIGHT * joins * root).flatten(1)], dim=1)

    def jacobian(self, residual, named: list, values, scale):
        """d residual / d u at the flat values (value = start + scale * u), by forward differences;
        with segments, every column the block can roll out (each constant, and the starts of every
        other segment moved at once: a segment's frames and joins depend on its own start and its
        neighbours' only) is one copy of a single batched rollout, so the Jacobian of hundreds of
        starting frames and the constants costs one rollout of 1 + constants + 2 * context * k
        copies of the segments."""
        import torch
        sizes = [p.numel() for _, p in named]
        parts = list(torch.split(values, sizes))
        swapped = {k: part.view_as(p) for (k, p), part in zip(named, parts)}
        batched = self.index is None
        if batched:
            r0, columns = self._batched_columns(swapped, named, parts, torch.split(scale, sizes))
        else:
            r0, columns = residual(swapped), {}
        cols = []
        for (key, p), part, sc in zip(named, parts, torch.split(scale, sizes)):
            if key in columns:
                cols.append(columns[key])
                continue
            for i in range(part.numel()):
                h = 1e-7 * float(sc[i])
                moved = dict(swapped)
                bumped = part.clone()
                bumped[i] += h
                moved[key] = bumped.view_as(p)
                cols.append(((residual(moved) - r0) / h * float(sc[i]))[:, None])
        return torch.cat(cols, dim=1), r0

    def _batched_columns(self, swapped, named: list, parts: list, scales) -> tuple:
        """The residual and the Jacobian's columns of the block's constants and the segments'
        starting frames ({key: (rows, n)}), from one batched rollout (see jacobian)."""
        import torch
        start = swapped["start"]
        n, nc, k = start.shape
        consts = {key: part.reshape(()) for (key, p), part in zip(named, parts) if key in self.models and p.numel() == 1}
        copies: list = [(start, dict(consts))]  # the first copy is the residual itself
        const_steps = []
        for (key, p), part, sc in zip(named, parts, scales):
            if key in consts:
                h = 1e-7 * float(sc[0])
                copies.append((start, {**consts, key: consts[key] + h}))
                const_steps.append((key, h, float(sc[0])))
            elif key == "start":
                start_scale = sc.view_as(p)
        seg = self.seg.numpy()
        jj = np.repeat(np.arange(n - 1), nc * k)
        owners, bumps = [], []
        for color in (0, 1) if n > 1 else (0,):
            mask = torch.as_tensor(np.arange(n) % 2 == color, dtype=start.dtype)[:, None]
            own_data = np.repeat(np.where(seg % 2 == color, seg, -1), k)
            own_join = np.where(jj % 2 == color, jj, jj + 1)
            owners.append(np.concatenate([own_data, own_join]))
            for i in range(nc):
                for c in range(k):
                    h = 1e-7 * start_scale[:, i, c]
                    bumped = start.clone()
                    bumped[:, i, c] += h * mask[:, 0]
                    copies.append((bumped, consts))
                    bumps.append((color, i, c, h))
        moved = self.pieces_residual(swapped, torch.stack([b for b, _ in copies]),
                                     {key: torch.stack([c[key] for _, c in copies]) for key in consts})
        r0 = moved[0]
        columns = {key: ((moved[1 + j] - r0) / h * sc)[:, None] for j, (key, h, sc) in enumerate(const_steps)}
        out = torch.zeros(r0.numel(), n * nc * k, dtype=r0.dtype)
        rows = np.arange(r0.numel())
        for (color, i, c, h), r in zip(bumps, moved[1 + len(const_steps):]):
            owner = owners[color]
            ok = owner >= 0
            cols = owner[ok] * nc * k + i * k + c
            d = (r - r0)[ok] / h[owner[ok]] * start_scale[owner[ok], i, c]
            out[rows[ok], cols] = d
        columns["start"] = out
        return r0, columns

    def residual(self, swapped):
        if self.index is None:
            return self.pieces_residual(swapped)[0]
        root = (1.0 / self.bent(swapped).var(dim=0).clamp_min(1e-24)).sqrt()  # every state counts equally
        data = self.difference(swapped) * root
        return (data if self.keep is None else data * self.keep).flatten()

    def misfit(self, swapped) -> float:
        """RMS of the frames' residual (the joins between segments left out), in spreads."""
        import torch
        root = (1.0 / self.bent(swapped).var(dim=0).clamp_min(1e-24)).sqrt()
        square = (self.difference(swapped) * root) ** 2
        if self.keep is not None:
            return float((square * self.keep).sum() / (self.keep.sum() * square.shape[1]).clamp_min(1)) ** 0.5
        return float(torch.mean(square)) ** 0.5


def _pieces(T: int, nc: int, segments: int):
    """Where each segment starts, the frames each rolls out, and for every frame its segment and
    its place in it. One segment is the whole trajectory, its Jacobian batched
    (trajectory._Problem.jacobian)."""
    import torch
    m = max(int(segments), nc + 1)
    n = max(1, -(-(T - nc) // m))  # the last segment starts at least `nc` frames before the end
    firsts = np.arange(n) * m
    t = np.arange(T)
    seg = np.clip((t - nc) // m, 0, n - 1)  # a segment's starting frames are read from the one before
    # one segment rolls out the path's own frames only (a short stretch of a dozen frames rolled out
    # 70 frames per trial cost six times its work); its rollout's frames are the same either way
    length = T if n == 1 else m + 2 * nc
    return firsts, length, torch.as_tensor(seg), torch.as_tensor(t - firsts[seg])


def _soft_l1(r, spread: float):
    return 2 * spread ** 2 * ((1 + (r / spread) ** 2).sqrt() - 1)


def _minimise(loss, named: list, scales: list, iterations: int) -> tuple[bool, int]:
    """L-BFGS with a strong-Wolfe line search in the scaled steps u (value = start + scale * u),
    on the loss relative to its start; the named tensors end at the minimum. (converged: it
    stopped on its tolerances before its iteration limit, iterations taken)."""
    import torch

    origin = [p.detach().clone() for _, p in named]
    steps = [torch.zeros_like(p, requires_grad=True) for _, p in named]

    def values():
        return {k: o + s * u for (k, _), o, s, u in zip(named, origin, scales, steps)}
    with torch.no_grad():
        first = float(loss(values()))
    norm = first if math.isfinite(first) and first > 0 else 1.0
    opt = _lbfgs(steps, max_iter=iterations, tolerance_grad=1e-12, tolerance_change=1e-15)

    def closure():
        for u in steps:
            u.grad = None
        value = loss(values()) / norm
        value.backward()
        return value
    opt.step(closure)
    with torch.no_grad():
        for (_, p), v in zip(named, values().values()):
            p.copy_(v)
    done = int(opt.state[opt._params[0]].get("n_iter", iterations))
    return done < iterations, done


def _lbfgs(params: list, max_iter: int, tolerance_grad: float, tolerance_change: float):
    """torch's L-BFGS (strong-Wolfe line search, lr 1), its steps exactly, without the bookkeeping
    of torch.optim.Optimizer: building any Optimizer imports torch._dynamo (its add_param_group and
    zero_grad are wrapped to keep the compiler out), which took as long as importing torch itself
    (2.5-3 s, loaded machine) in every process whose fit reaches this solver (the checks of a
    learned latent, the refit of a short calibrated path), for nothing it uses. LBFGS.step reads
    only the fields set here (and, where another LBFGS in the process had its step wrapped for the
    profiler, the two hook tables)."""
    from collections import OrderedDict, defaultdict

    from torch.optim import LBFGS

    opt = LBFGS.__new__(LBFGS)
    opt.defaults = {"lr": 1.0, "max_iter": max_iter, "max_eval": max_iter * 5 // 4, "tolerance_grad": tolerance_grad,
                    "tolerance_change": tolerance_change, "history_size": 100, "line_search_fn": "strong_wolfe"}
    opt.param_groups = [{"params": list(params), **opt.defaults}]
    opt.state = defaultdict(dict)
    opt._params, opt._numel_cache = opt.param_groups[0]["params"], None
    opt._optimizer_step_pre_hooks, opt._optimizer_step_post_hooks = OrderedDict(), OrderedDict()
    return opt


def _levenberg(problem: _Problem, named: list, scales: list, iterations: int) -> tuple[bool, int, int]:
    """Levenberg-Marquardt in the scaled steps u (value = start + scale * u) on the residual
    vector, the Jacobian by forward differences; the named tensors end at the minimum. Bounded:
    at most `iterations` steps (a Jacobian each), TRIALS dampings within one step and
    TRIALS_PER_STEP * iterations trial rollouts in all (a wrong basin where the cost creeps down
    by a little each step ran for many minutes). (converged, steps, trial rollouts): converged
    where the cost stopped falling within the bounds."""
    import torch

    from fitode.errors import FitodeError

    sizes = [p.numel() for _, p in named]
    origin = torch.cat([p.detach().flatten() for _, p in named])
    scale = torch.cat([s.flatten() for s in scales])

    def r(u):
        v = origin + scale * u
        return problem.residual({k: part.view_as(p) for (k, p), part in zip(named, torch.split(v, sizes))})
    u = torch.zeros_like(origin)
    with torch.no_grad():
        res = r(u)
    cost = float(res @ res)
    if not math.isfinite(cost):
        raise FloatingPointError("the starting point leaves the equation's domain")
    # small damping: the starting frames are nearly collinear, and a damping of the diagonal's
    # 1e-3 held the steps along them back for dozens of iterations on a linear problem
    damping, converged, steps, trials = 1e-10, False, 0, 0
    budget = TRIALS_PER_STEP * iterations
    while steps < iterations and trials < budget:
        steps += 1
        with torch.no_grad():
            jac = problem.jacobian(problem.residual, named, origin + scale * u, scale)[0]
        a, g = jac.T @ jac, jac.T @ res
        diag = a.diagonal().clamp_min(1e-12)
        improved = settled = False
        for _ in range(TRIALS):
            step = torch.linalg.solve(a + damping * torch.diag(diag), -g)
            if float(-(g @ step)) <= 1e-8 * cost:  # the model promises nothing more: at the minimum
                settled = True
                break
            if trials >= budget:
                break
            trials += 1
            try:
                with torch.no_grad():
                    trial = r(u + step)
                new = float(trial @ trial)
            except (FitodeError, RuntimeError, FloatingPointError, ValueError):  # the step left the domain
                new = math.inf
            if math.isfinite(new) and new < cost:
                improved = True
                break
            damping *= 10.0
        if not improved:
            converged = settled or trials < budget  # no damping lowers the cost: at the minimum
            break
        u, res, drop, cost = u + step, trial, cost - new, new
        damping = max(damping / 10.0, 1e-15)
        if drop <= 1e-7 * cost + 1e-300:  # a relative change this small moves no constant visibly
            converged = True
            break
    with torch.no_grad():
        for (_, p), part in zip(named, torch.split(origin + scale * u, sizes)):
            p.copy_(part.view_as(p))
    return converged, steps, trials


def _summary(block, problem: _Problem, named: list, scales: list, converged: bool,
             robust: bool) -> TrajectoryFit | None:
    import torch

    sizes = [p.numel() for _, p in named]
    flat = torch.cat([p.detach().flatten() for _, p in named])
    scale = torch.cat([s.flatten() for s in scales])

    def residual(v):
        return problem.residual({k: part.view_as(p) for (k, p), part in zip(named, torch.split(v, sizes))})
    with torch.no_grad():
        r = residual(flat).detach()
    with torch.no_grad():  # forward differences: forward-mode AD through the generated field takes a slow path
        jac = problem.jacobian(problem.residual, named, flat, scale)[0] / scale
    if robust:  # the soft-L1 weights, as in iteratively reweighted least squares
        spread = 1.4826 * float((r - r.median()).abs().median()) or 1.0
        w = (1 + (r / spread) ** 2) ** -0.25
        r, jac = r * w, jac * w[:, None]
    dof = max(r.numel() - flat.numel(), 1)
    lag = float((r[1:] @ r[:-1]) / (r @ r).clamp_min(1e-300)) if r.numel() > 2 else 0.0
    lag = min(max(lag, 0.0), 0.95)
    scaled = jac * scale  # in the scaled steps, where the normal matrix is well conditioned
    cov = scale[:, None] * torch.linalg.pinv(scaled.T @ scaled, hermitian=True) * scale[None, :] * float(r @ r) / dof \
        * (1 + lag) / (1 - lag)
    swapped = dict(named)
    outputs = dict(block.constants())
    if problem.bend:
        outputs[PERSPECTIVE] = problem.perspective(swapped)
    values, errors = {}, {}
    for name, value in outputs.items():
        grads = torch.autograd.grad(value, [p for _, p in named], allow_unused=True)
        g = torch.cat([(gr if gr is not None else torch.zeros_like(p)).flatten() for gr, (_, p) in zip(grads, named)])
        values[name] = float(value.detach())
        errors[name] = float((g @ cov @ g).clamp_min(0).sqrt())
    with torch.no_grad():
        difference = problem.difference(swapped).double().numpy()
        misfit = problem.misfit(swapped)
    if not all(math.isfinite(v) for v in [*values.values(), *errors.values(), misfit]):
        return None
    start = swapped["start"].detach().numpy().copy() if "start" in swapped else None
    if start is not None and start.ndim == 3:  # segments: the first one's starting frames
        start = start[0]
    gauge = None
    if problem.learn_scale or problem.learn_offset:
        s, b = (v.detach() for v in problem.gauge(swapped))
        gauge = {st: {"scale": float(s[i]), "offset": float(b[i])} for i, st in enumerate(block.system.states)}
    return TrajectoryFit(values, errors, misfit, difference, converged, problem.windows, start, gauge)


def trajectory_misfit(system, params: Mapping, x: np.ndarray, dt: float, values: Mapping[str, float], *,
                      integrator: str = "rk4", substeps: int = 1, windows: int | None = None,
                      max_windows: int = MAX_WINDOWS, gauge: Mapping | None = None) -> float:
    """The misfit fit_trajectory would start from with these constants, the whole trajectory
    starting from x's own first frames (inf where the equation cannot be rolled out): a cheap
    score to choose among starting points."""
    import torch

    from fitode.codegen import PhysicsBlock
    from fitode.errors import FitodeError

    xt = torch.as_tensor(np.asarray(x, dtype=np.float64)).reshape(len(x), -1)
    try:
        block = PhysicsBlock(system, params, integrator=integrator, substeps=substeps, dtype=torch.float64)
        block.set_constants({n: float(values[n]) for n in system.learnable})
        problem = _Problem(block, xt, dt, windows, False, max_windows, gauge)
        with torch.no_grad(), _one_thread():
            value = float(torch.mean(problem.residual(dict(problem.extra) | dict(block.named_parameters())) ** 2))
    except (FitodeError, RuntimeError, FloatingPointError, ValueError):
        return math.inf
    return value ** 0.5 if math.isfinite(value) else math.inf
