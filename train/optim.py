"""Adam for R restarts stacked in one tensor, with a learning-rate multiplier per restart.

torch.optim.Adam has one learning rate per parameter group; restarts batched along a leading
axis need their own (a run that has settled works at a tenth of its rate while the others go on)
and a way to freeze a run that converged or failed without touching its neighbours. The update
is torch's Adam formula, element for element, so each restart moves exactly as it would alone.

The moments of every parameter live side by side in one (R, N) buffer, and a step gathers the
gradients into one (R, N) tensor: a dozen operations a step whatever the number of parameters,
where one set per parameter cost a fifth of the training time (the tensors are small, so each
operation's fixed cost is most of its cost).
"""
from __future__ import annotations

import torch


class BatchedAdam:
    """groups: [{"params": [tensors with a leading restart axis], "lr": float, "name": str}]."""

    def __init__(self, groups: list[dict], restarts: int, betas: tuple[float, float] = (0.9, 0.999),
                 eps: float = 1e-8):
        self.groups = groups
        self.restarts = restarts
        self.betas = betas
        self.eps = eps
        ref = next(p for g in groups for p in g["params"])
        dtype, device = ref.dtype, ref.device
        self.lr_mult = torch.ones(restarts, dtype=dtype, device=device)
        self.steps = torch.zeros(restarts, dtype=dtype, device=device)
        self._params = [p for g in groups for p in g["params"]]
        sizes = [p[0].numel() for p in self._params]
        self._slices: dict[int, slice] = {}
        start = 0
        for p, n in zip(self._params, sizes):
            self._slices[id(p)] = slice(start, start + n)
            start += n
        lrs = [float(g["lr"]) for g in groups for _ in g["params"]]
        self._lr = torch.cat([torch.full((n,), lr, dtype=dtype, device=device) for n, lr in zip(sizes, lrs)])[None]
        self._m = torch.zeros(restarts, start, dtype=dtype, device=device)
        self._v = torch.zeros(restarts, start, dtype=dtype, device=device)
        self._gathered: torch.Tensor | None = None

    def params(self):
        return list(self._params)

    def _view(self, flat: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
        return flat[:, self._slices[id(p)]].view(p.shape)

    def zero_grad(self) -> None:
        for p in self._params:
            p.grad = None
        self._gathered = None

    def _gradients(self) -> torch.Tensor:
        """(R, N) every parameter's gradient side by side; zeros where a parameter has none.
        Gathered once per step: finite_grads and step read the same gradients (zero_grad and step
        forget them)."""
        if self._gathered is None:
            self._gathered = self._gather()
        return self._gathered

    def _gather(self) -> torch.Tensor:
        return torch.cat([p.grad.reshape(self.restarts, -1) if p.grad is not None else
                          torch.zeros(self.restarts, self._slices[id(p)].stop - self._slices[id(p)].start,
                                      dtype=self._m.dtype, device=self._m.device)
                          for p in self._params], dim=1)

    def finite_grads(self) -> torch.Tensor:
        """(R,) True where every gradient of that restart is finite (no host synchronisation)."""
        return torch.isfinite(self._gradients()).all(dim=1)

    @torch.no_grad()
    def rescaled(self, p: torch.Tensor, factor: torch.Tensor) -> None:
        """p was divided by factor (R,), so its gradients grow by factor: carry Adam's moments into
        the new units (m by factor, v by its square), so the gradients seen so far keep their say."""
        cols = self._slices[id(p)]
        f = factor.to(self._m.dtype).reshape(self.restarts, 1)
        self._m[:, cols] *= f
        self._v[:, cols] *= f * f

    @torch.no_grad()
    def step(self, active: torch.Tensor) -> None:
        """One Adam step for the restarts where `active` (R,) is True; the others do not move at all.
        A parameter without a gradient does not move, and its moments stay as they were."""
        b1, b2 = self.betas
        self.steps += active.to(self.steps.dtype)
        t = self.steps.clamp_min(1)
        bc1 = (1 - b1 ** t)[:, None]
        bc2_sqrt = torch.sqrt(1 - b2 ** t)[:, None]
        zero = torch.zeros((), dtype=self._m.dtype, device=self._m.device)
        on = active.reshape(self.restarts, 1)
        missing = [self._slices[id(p)] for p in self._params if p.grad is None]
        if missing:  # frozen columns: no moment update, no step
            on = on.expand(self.restarts, self._m.shape[1]).clone()
            for cols in missing:
                on[:, cols] = False
        grad = torch.where(on, self._gradients(), zero)
        self._m.copy_(torch.where(on, self._m * b1 + grad * (1 - b1), self._m))
        self._v.copy_(torch.where(on, self._v * b2 + grad * grad * (1 - b2), self._v))
        step_size = self._lr * self.lr_mult[:, None] / bc1
        denom = (self._v.sqrt() / bc2_sqrt) + self.eps
        update = torch.where(on, step_size * self._m / denom, zero)
        torch._foreach_sub_(self._params, [self._view(update, p) for p in self._params])
        self._gathered = None
