"""PhysicsBlock: the paper's physics block for any OdeSystem, and `simulate` for fixed constants."""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import torch
from torch import nn

from fitode.eqparse import OdeSystem, ParamSpec

from .constants import Reparam, reparam_for
from .differences import InitScheme, init_scheme
from .errors import NonFiniteError, ParameterError
from .guard import explain_nonfinite
from .integrators import get_integrator
from .layout import StateLayout
from .source import compile_numpy, compile_system, generate_source


class PhysicsBlock(nn.Module):
    """Learnable constants + initial state from the first frames + rollout of the equation.

    forward(z_head, n_frames, dt, window_index=None): z_head holds the encoded latents of the
    first frames of each window, shape (..., >= n_context, dim) (extra frames are ignored); the
    result, shape (..., n_frames, dim), is the physics prediction of frames 0..n_frames-1 of each
    window. Frames before the anchor frame (see fitode.codegen.differences) are copied from
    z_head, the anchor is z_head's own value, every later frame is the rollout.

    Parameters
    ----------
    system: the equation (fitode.eqparse.OdeSystem).
    params: ParamSpec per learnable constant (init, min, max); missing ones start at 1.0 or a
        value inside their bounds. Bounds are kept by reparametrisation (fitode.codegen.constants).
    integrator: "rk4" (default), "symplectic" (the paper's scheme; alias "paper") or "euler".
    substeps: integrator steps per frame interval (h = dt / substeps).
    initial_state: "difference" (centred finite differences), "backward" (the paper's one-sided
        ones) or "learnable" (per-window initial derivatives, initialised by the centred
        differences the first time a window is seen; needs n_windows, and window_index in
        forward: without it the block falls back to the differences).
    context: number of leading frames used for the initial state (default by init; see
        fitode.codegen.differences).
    dtype: dtype of the constants' parameters and of the fixed constants.
    check_finite: raise NonFiniteError instead of returning NaN/inf (one isfinite().all() per
        forward, a host synchronisation).
    restarts: None for one set of constants (0-d parameters), or R for R restarts trained as one
        batched model: every constant is then an (R,) parameter, z_head is (R, B, n_context, dim)
        and the output (R, B, n_frames, dim). Each restart's paper lr scale (10**floor(log10|v|)
        of its own start) is folded into its parametrisation (value = raw * scale), because one
        Adam learning rate per tensor cannot differ between restarts; Adam is invariant to that
        rescaling, so each restart moves exactly as it would alone with lr * scale.
    """

    def __init__(self, system: OdeSystem, params: Mapping[str, ParamSpec] | None = None, *,
                 integrator: str = "rk4", substeps: int = 1, initial_state: str = "difference",
                 n_windows: int | None = None, dtype: torch.dtype = torch.float32,
                 context: int | None = None, check_finite: bool = True, restarts: int | None = None):
        super().__init__()
        if int(substeps) < 1:
            raise ParameterError(f"substeps must be at least 1, not {substeps}")
        self.system = system
        self.field = compile_system(system)
        self._numpy_field = None
        self.layout: StateLayout = self.field.layout
        self.integrator_name = get_integrator(integrator).name
        self.integrator = get_integrator(integrator)(self.layout)
        self.substeps = int(substeps)
        self.initial_state_mode = initial_state
        self.scheme: InitScheme = init_scheme(self.layout.max_order, initial_state, context)
        self.check_finite = check_finite
        if restarts is not None and int(restarts) < 1:
            raise ParameterError(f"restarts must be at least 1, not {restarts}")
        self.restarts = None if restarts is None else int(restarts)
        shape = () if self.restarts is None else (self.restarts,)

        params = dict(params or {})
        self._reparams: dict[str, Reparam] = {}
        self._scale_values: dict[str, float] = {}
        self._param_attr: dict[str, str] = {}
        lay = self.layout
        for name, ident in zip(lay.constants[:lay.n_learnable], lay.const_idents[:lay.n_learnable]):
            rep, v0 = reparam_for(name, params.get(name))
            self._reparams[name] = rep
            self._scale_values[name] = v0
            self._param_attr[name] = "const_" + ident
            self.register_parameter("const_" + ident, nn.Parameter(torch.full(shape, rep.raw(v0), dtype=dtype)))
            if self.restarts is not None:
                self.register_buffer("scale_" + ident, torch.ones(shape, dtype=dtype))
        fixed = [float(system.fixed[n]) for n in lay.constants[lay.n_learnable:]]
        self.register_buffer("fixed_values", torch.tensor(fixed, dtype=dtype))

        states = {s: i for i, s in enumerate(lay.states)}
        self._slot_src = [s.k * lay.dim + states[s.state] for s in lay.slots]
        self._value_slots = list(lay.value_slots)
        self._deriv_slots = list(lay.derivative_slots)
        self._weights_cache: dict = {}
        self.n_windows = n_windows
        if initial_state == "learnable":
            if not n_windows or n_windows < 1:
                raise ParameterError("initial_state='learnable' needs n_windows (the number of distinct windows)")
            self.initial_derivatives = nn.Parameter(torch.zeros(*shape, n_windows, len(self._deriv_slots),
                                                                dtype=dtype))
            self.register_buffer("initialised", torch.zeros(n_windows, dtype=torch.bool))
            # Learnable slots come after the encoder's values in one concatenated source row.
            pos = {slot: j for j, slot in enumerate(self._value_slots)}
            pos.update({slot: lay.dim + j for j, slot in enumerate(self._deriv_slots)})
            self._learnable_perm = [pos[i] for i in range(lay.n_slots)]

    # ----------------------------------------------------------------- shape facts
    @property
    def dim(self) -> int:
        """Number of latent dimensions: one per state variable."""
        return self.layout.dim

    @property
    def n_context(self) -> int:
        """Leading frames of a window the block reads to build the initial state."""
        return self.scheme.context

    @property
    def anchor(self) -> int:
        """Frame of the window at which the rollout starts (frames before it are copied)."""
        return self.scheme.anchor

    @property
    def source(self) -> str:
        """The generated source of the vector field, with comments on integrator and initial state."""
        return generate_source(self.system, integrator=self.integrator_name, substeps=self.substeps,
                               initial_state=self.initial_state_mode, context=self.scheme.context)

    # ----------------------------------------------------------------- constants
    def _param(self, name: str) -> nn.Parameter:
        try:
            return getattr(self, self._param_attr[name])
        except KeyError:
            raise ParameterError(f"{name} is not a learnable constant of this equation "
                                 f"(learnable: {', '.join(self._reparams) or 'none'})") from None

    def _raw(self, name: str) -> torch.Tensor:
        u = self._param(name)
        if self.restarts is not None and self._reparams[name].kind == "identity":
            return u * getattr(self, "scale_" + self._param_attr[name][len("const_"):])
        return u

    def constants(self) -> dict[str, torch.Tensor]:
        """Current values of the learnable constants (0-d tensors, or (R,) with restarts; in the
        autograd graph)."""
        return {n: rep.value(self._raw(n)) for n, rep in self._reparams.items()}

    def values_of(self, parameters: Mapping[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The learnable constants' values for raw parameters named as named_parameters() names
        them (each of any shape: one value per rollout of a batch), without restarts."""
        return {n: rep.value(parameters[self._param_attr[n]]) for n, rep in self._reparams.items()}

    def fixed_constants(self) -> dict[str, float]:
        lay = self.layout
        return dict(zip(lay.constants[lay.n_learnable:], self.fixed_values.tolist()))

    def set_constants(self, values: Mapping[str, float | Sequence[float]], *, clip: bool = False) -> None:
        """Set learnable constants (e.g. for a restart). Values must lie strictly inside the
        bounds, or are moved just inside them with clip=True. lr_scale follows the new value.
        With restarts, a value is one number for every restart or a sequence of R numbers."""
        for name, v in values.items():
            rep = self._reparams.get(name)
            if rep is None:
                self._param(name)  # raises the ParameterError
            if self.restarts is None:
                v = rep.clip(float(v)) if clip else float(v)
                with torch.no_grad():
                    self._param(name).fill_(rep.raw(v))
                self._scale_values[name] = v
                continue
            vs = [float(v)] * self.restarts if isinstance(v, (int, float)) else [float(x) for x in v]
            if len(vs) != self.restarts:
                raise ParameterError(f"{name}: {len(vs)} values for {self.restarts} restarts")
            vs = [rep.clip(x) if clip else x for x in vs]
            scales = [rep.lr_scale(x) for x in vs]
            with torch.no_grad():
                self._param(name).copy_(torch.tensor([rep.raw(x) / sc for x, sc in zip(vs, scales)]))
                if rep.kind == "identity":
                    getattr(self, "scale_" + self._param_attr[name][len("const_"):]).copy_(torch.tensor(scales))

    @torch.no_grad()
    def follow_scales(self) -> dict[str, torch.Tensor]:
        """Grow each restart's lr scale of an unbounded constant to follow its value (restarts only).

        The paper's rule fixes the step from the start's magnitude, so a constant started at 0.5
        climbs to 4 at 0.005 per step. Once |value| has grown past the next power of ten, its scale
        becomes that power (never smaller than the start's, so a constant on its way through zero
        keeps its pace). The raw parameter is divided by the growth so the value stays put.
        Returns {name: (R,) growth factor} for the constants whose scale grew (for the optimiser's
        moments), empty when none did.
        """
        grown: dict[str, torch.Tensor] = {}
        if self.restarts is None:
            return grown
        for name, rep in self._reparams.items():
            if rep.kind != "identity":
                continue
            u = self._param(name)
            scale = getattr(self, "scale_" + self._param_attr[name][len("const_"):])
            mag = (u * scale).abs().clamp_min(1e-30)
            target = torch.where(torch.isfinite(mag), 10.0 ** torch.floor(torch.log10(mag)), scale)
            factor = torch.clamp(target / scale, min=1.0)
            if bool((factor > 1).any()):
                u.div_(factor)
                scale.mul_(factor)
                grown[name] = factor
        return grown

    def bounds(self, name: str) -> tuple[float | None, float | None]:
        self._param(name)
        return self._reparams[name].lo, self._reparams[name].hi

    def parametrisation(self, name: str) -> str:
        """"identity", "log-lower", "log-upper" or "sigmoid" (see fitode.codegen.constants)."""
        self._param(name)
        return self._reparams[name].kind

    def lr_scale(self, name: str) -> float:
        """Multiplier of the base lr for constant `name` (fitode.codegen.constants has the table);
        "initial_derivatives" -> 1, and 1 for every constant with restarts (folded in, see above)."""
        if name == "initial_derivatives" and self.initial_state_mode == "learnable":
            return 1.0
        self._param(name)
        if self.restarts is not None:
            return 1.0
        return self._reparams[name].lr_scale(self._scale_values[name])

    def param_groups(self, lr: float = 1.0) -> list[dict]:
        """Optimizer groups: one per learnable constant ({"params", "lr", "name", "kind":
        "constant"}), plus, with init="learnable", one {"name": "initial_derivatives", "kind":
        "initial_state"} group holding the per-window derivatives."""
        groups = [{"params": [self._param(n)], "lr": lr * self.lr_scale(n), "name": n, "kind": "constant"}
                  for n in self._reparams]
        if self.initial_state_mode == "learnable":
            groups.append({"params": [self.initial_derivatives], "lr": lr, "name": "initial_derivatives",
                           "kind": "initial_state"})
        return groups

    def _const_args(self, restarts: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
        learn = tuple(self.constants().values())
        if self.restarts is not None:  # (R,) -> (R, 1): broadcast over each restart's windows
            learn = tuple((c if restarts is None else c[restarts])[:, None] for c in learn)
        return learn + tuple(self.fixed_values.unbind(0))

    # ----------------------------------------------------------------- initial state
    def _weights(self, ref: torch.Tensor, dt: float) -> torch.Tensor:
        key = (ref.device, ref.dtype, float(dt))
        w = self._weights_cache.get(key)
        if w is None:
            rows = [[wj / float(dt) ** k for wj in row] for k, row in enumerate(self.scheme.weights)]
            w = torch.tensor(rows, dtype=ref.dtype, device=ref.device)
            if len(self._weights_cache) > 16:
                self._weights_cache.clear()
            self._weights_cache[key] = w
        return w

    def difference_state(self, z_head: torch.Tensor, dt: float) -> torch.Tensor:
        """The finite-difference state at the anchor, (..., n_slots), from z_head (..., n_context, dim)."""
        d = torch.matmul(self._weights(z_head, dt), z_head)  # einsum took 2000x longer here (float64, batched)
        return d.reshape(*d.shape[:-2], -1)[..., self._slot_src]

    @torch.no_grad()
    def init_from(self, z_head: torch.Tensor, window_index: torch.Tensor, dt: float) -> None:
        """Set the learnable initial derivatives of these windows from finite differences."""
        if self.initial_state_mode != "learnable":
            raise ParameterError("init_from needs initial_state='learnable'")
        idx = window_index.reshape(-1).to(self.initial_derivatives.device)
        y0 = self.difference_state(self._head(z_head), dt)
        self.initial_derivatives[..., idx, :] = y0[..., self._deriv_slots].to(self.initial_derivatives)
        self.initialised[idx] = True

    def initial_state(self, z_head: torch.Tensor, dt: float,
                      window_index: torch.Tensor | None = None) -> torch.Tensor:
        """The state at the anchor frame for each window, (..., B, n_slots), from z_head
        (..., B, n_context, dim)."""
        y0 = self.difference_state(z_head, dt)
        if self.initial_state_mode != "learnable" or window_index is None:
            return y0  # without window_index (a rollout of the whole video) no per-window values apply
        idx = window_index.reshape(-1).to(self.initial_derivatives.device)
        if idx.numel() != z_head.shape[-3]:
            raise ValueError(f"window_index has {idx.numel()} entries for {z_head.shape[-3]} windows")
        new = ~self.initialised[idx]
        if new.any():
            self.init_from(z_head[..., new.to(z_head.device), :, :], idx[new], dt)
        learned = self.initial_derivatives[..., idx, :].to(device=z_head.device, dtype=z_head.dtype)
        return torch.cat([y0[..., self._value_slots], learned], dim=-1)[..., self._learnable_perm]

    def _head(self, z_head: torch.Tensor, restarts: int | None = None) -> torch.Tensor:
        """z_head cut to the context frames: (B, n_context, dim), or (R, B, n_context, dim) with
        restarts (R = `restarts` where the caller rolls out only some of them)."""
        if z_head.dim() < 2 or z_head.shape[-1] != self.dim:
            raise ValueError(f"z_head must have shape (..., n_context, {self.dim}), got {tuple(z_head.shape)}")
        if z_head.shape[-2] < self.n_context:
            raise ValueError(f"z_head has {z_head.shape[-2]} frame(s); this block needs {self.n_context}")
        zh = z_head[..., :self.n_context, :]
        if self.restarts is None:
            return zh.reshape(-1, self.n_context, self.dim)
        r = self.restarts if restarts is None else restarts
        if z_head.dim() != 4 or z_head.shape[0] != r:
            raise ValueError(f"with {r} restarts z_head must be ({r}, B, n_context, "
                             f"{self.dim}), got {tuple(z_head.shape)}")
        return zh

    # ----------------------------------------------------------------- rollout
    def forward(self, z_head: torch.Tensor, n_frames: int, dt: float,
                window_index: torch.Tensor | None = None, restarts: torch.Tensor | None = None) -> torch.Tensor:
        """The rollout of every window from its first frames z_head; with restarts (indices, R
        restarts only), z_head holds those restarts only and only their constants are used, so a
        training loop does no work for restarts that have stopped."""
        lead = z_head.shape[:-2]
        if restarts is not None and (self.restarts is None or self.initial_state_mode == "learnable"):
            raise ParameterError("a rollout of some restarts needs restarts and an initial state from differences")
        zh = self._head(z_head, None if restarts is None else int(restarts.numel()))
        anchor = self.scheme.anchor
        if n_frames < anchor + 1:
            raise ValueError(f"n_frames = {n_frames}: the rollout starts at frame {anchor}")
        dt = float(dt)
        y0 = self.initial_state(zh, dt, window_index)
        consts = self._const_args(restarts)
        fn = self.field.fn
        traj = self.integrator.rollout(lambda y: fn(y, *consts), y0, n_frames - anchor, dt, self.substeps)
        pred = traj if len(self._value_slots) == traj.shape[-1] else traj[..., self._value_slots]
        out = torch.cat([zh[..., :anchor, :], pred], dim=-2) if anchor else pred
        if self.check_finite and not bool(torch.isfinite(out).all()):
            raise self.explain(zh, n_frames, dt)
        return out if self.restarts is not None else out.reshape(*lead, n_frames, self.dim)

    def rollout_numpy(self, z_head: np.ndarray, n_frames: int, dt: float, values: Sequence) -> np.ndarray:
        """forward() in NumPy without gradients, for many sets of constants at once: z_head
        (B, n_context, dim), values the learnable constants' values in the layout's order, each a
        number or a (B,) array (one per window). (B, n_frames, dim), non-finite where a rollout
        leaves the equation's domain (the caller checks)."""
        if self.initial_state_mode == "learnable":
            raise ParameterError("a NumPy rollout needs an initial state from differences")
        anchor, dt = self.scheme.anchor, float(dt)
        if n_frames < anchor + 1:
            raise ValueError(f"n_frames = {n_frames}: the rollout starts at frame {anchor}")
        zh = np.asarray(z_head, dtype=np.float64)[:, :self.n_context]
        weights = np.array([[wj / dt ** k for wj in row] for k, row in enumerate(self.scheme.weights)])
        y0 = (weights @ zh).reshape(len(zh), -1)[:, self._slot_src]
        consts = tuple(values) + tuple(self.fixed_values.tolist())
        if self._numpy_field is None:  # compiled on first use: the training never asks for it
            self._numpy_field = compile_numpy(self.system)
        fn = self._numpy_field
        roll = self.integrator.rollout_affine if self.layout.affine else self.integrator.rollout
        with np.errstate(all="ignore"):  # a rollout that leaves the domain is the caller's finding, not a warning
            traj = roll(lambda y: fn(y, *consts), y0, n_frames - anchor, dt, self.substeps)
        pred = traj if len(self._value_slots) == traj.shape[-1] else traj[..., self._value_slots]
        return np.concatenate([zh[:, :anchor], pred], axis=1) if anchor else pred

    def explain(self, z_head: torch.Tensor, n_frames: int, dt: float, restart: int | None = None) -> NonFiniteError:
        """What went non-finite in the rollout of these windows (of one restart, with restarts)."""
        zh = self._head(z_head)
        consts = self._const_args()
        if self.restarts is not None:
            r = 0 if restart is None else int(restart)
            zh = zh[r]
            consts = tuple(c[r, 0] if c.dim() == 2 else c for c in consts)
        if not bool(torch.isfinite(zh).all()):
            return NonFiniteError("the encoded frames given to the physics block contain NaN or inf", term="z_head")
        y0 = self.difference_state(zh, float(dt))
        return explain_nonfinite(self.field, self.integrator, y0, consts, n_frames - self.scheme.anchor, float(dt),
                                 self.substeps, frame_offset=self.scheme.anchor)

    def extra_repr(self) -> str:
        consts = ", ".join(f"{n}={v.tolist()}" for n, v in self.constants().items())
        return (f"{'; '.join(self.system.normal_form())}, integrator={self.integrator_name}, "
                f"substeps={self.substeps}, initial_state={self.initial_state_mode}, n_context={self.n_context}, {consts}")


def _initial_vector(layout: StateLayout, y0, dtype, device) -> torch.Tensor:
    if isinstance(y0, torch.Tensor):
        if y0.shape[-1] != layout.n_slots:
            raise ParameterError(f"y0 must have {layout.n_slots} entries per state "
                                 f"({', '.join(s.label for s in layout.slots)}), got {tuple(y0.shape)}")
        return y0.to(dtype=dtype, device=device)
    missing = [s for s in layout.states if s not in y0]
    extra = [s for s in y0 if s not in layout.states]
    if missing or extra:
        raise ParameterError(f"y0 needs exactly the states {', '.join(layout.states)}"
                             + (f"; missing {', '.join(missing)}" if missing else "")
                             + (f"; unknown {', '.join(extra)}" if extra else ""))
    values = []
    for state, order in zip(layout.states, layout.orders):
        given = y0[state]
        given = [given] if isinstance(given, (int, float)) else list(given)
        if len(given) != order:
            labels = ", ".join(state + "'" * k for k in range(order))
            raise ParameterError(f"y0[{state!r}] needs {order} value(s): {labels}")
        values += [float(v) for v in given]
    return torch.tensor(values, dtype=dtype, device=device)


def simulate(system: OdeSystem, constants: Mapping[str, float],
             y0: Mapping[str, Sequence[float] | float] | torch.Tensor, n_frames: int, dt: float,
             integrator: str = "rk4", substeps: int = 1, *, dtype: torch.dtype = torch.float64,
             device: torch.device | str | None = None, full: bool = False, numpy: bool = False) -> torch.Tensor:
    """Roll `system` out from a full initial state with fixed constants.

    constants: a value for every learnable constant (fixed ones may be overridden too).
    y0: {state: [value, derivative, ..., derivative of order-1]} (a bare number for a first-order
        state), or a tensor (..., n_slots) in the layout order of StateLayout.from_system(system).
    Returns the states' values at frames 0..n_frames-1 (frame 0 = y0), shape (n_frames, dim) for
    a mapping y0 or (..., n_frames, dim) for a tensor; with full=True every slot instead
    (..., n_frames, n_slots). Raises NonFiniteError naming the term that went non-finite.
    For ground truth, use RK4 with enough substeps that dt/substeps resolves the dynamics.
    numpy: the same steps on the equation's NumPy code (compile_numpy), a float64 NumPy array back:
    one trajectory's thousands of steps cost a few times less than in torch, and need no gradient.
    """
    vf = compile_system(system)
    lay = vf.layout
    missing = [n for n in system.learnable if n not in constants]
    unknown = [n for n in constants if n not in lay.constants]
    if missing or unknown:
        raise ParameterError("simulate: " + "; ".join(
            ([f"no value for {', '.join(missing)}"] if missing else [])
            + ([f"{', '.join(unknown)} is not a constant of the equation"] if unknown else [])))
    if int(substeps) < 1 or int(n_frames) < 1:
        raise ParameterError("simulate needs n_frames >= 1 and substeps >= 1")
    consts = tuple(torch.tensor(float(constants[n] if n in constants else system.fixed[n]), dtype=dtype,
                                device=device) for n in lay.constants)
    y = _initial_vector(lay, y0, dtype, device)
    integ = get_integrator(integrator)(lay)
    if numpy:
        field, values = compile_numpy(system), tuple(float(c) for c in consts)
        with np.errstate(all="ignore"):  # a trajectory that leaves the domain is explained below
            traj = integ.rollout(lambda s: field(s, *values), y.detach().cpu().numpy().astype(np.float64),
                                 int(n_frames), float(dt), int(substeps))
        if np.all(np.isfinite(traj)):
            return traj if full else traj[..., list(lay.value_slots)]
        traj = torch.as_tensor(traj)
    else:
        traj = integ.rollout(lambda s: vf.fn(s, *consts), y, int(n_frames), float(dt), int(substeps))
    if not bool(torch.isfinite(traj).all()):
        raise explain_nonfinite(vf, integ, y.reshape(-1, lay.n_slots), consts, int(n_frames), float(dt),
                                int(substeps))
    return traj if full else traj[..., list(lay.value_slots)]
