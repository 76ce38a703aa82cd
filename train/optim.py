"""Adam for R restarts stacked in one tensor, with a learning-rate multiplier per restart.

torch.optim.Adam has one learning rate per parameter group; restarts batched along a leading
axis need their own (a run that has settled works at a tenth of its rate while the others go on)
and a way to freeze a run that converged or failed without touching its neighbours. The update
is torch's Adam formula, element for element, so each restart moves exactly as it would alone.
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
        self.lr_mult = torch.ones(restarts, dtype=ref.dtype, device=ref.device)
        self.steps = torch.zeros(restarts, dtype=ref.dtype, device=ref.device)
        self.state = {id(p): (torch.zeros_like(p), torch.zeros_like(p)) for g in groups for p in g["params"]}

    def params(self):
        return [p for g in self.groups for p in g["params"]]

    def zero_grad(self) -> None:
        for p in self.params():
            p.grad = None

    def finite_grads(self) -> torch.Tensor:
        """(R,) True where every gradient of that restart is finite (no host synchronisation)."""
        ok = torch.ones(self.restarts, dtype=torch.bool, device=self.lr_mult.device)
        for p in self.params():
            if p.grad is not None:
                ok &= torch.isfinite(p.grad).reshape(self.restarts, -1).all(dim=1)
        return ok

    @torch.no_grad()
    def rescaled(self, p: torch.Tensor, factor: torch.Tensor) -> None:
        """p was divided by factor (R,), so its gradients grow by factor: carry Adam's moments into
        the new units (m by factor, v by its square), so the gradients seen so far keep their say."""
        m, v = self.state[id(p)]
        shape = (self.restarts,) + (1,) * (p.dim() - 1)
        f = factor.to(p.dtype).reshape(shape)
        m.mul_(f)
        v.mul_(f * f)

    @torch.no_grad()
    def step(self, active: torch.Tensor) -> None:
        """One Adam step for the restarts where `active` (R,) is True; the others do not move at all."""
        b1, b2 = self.betas
        self.steps += active.to(self.steps.dtype)
        t = self.steps.clamp_min(1)
        bc1 = 1 - b1 ** t
        bc2_sqrt = torch.sqrt(1 - b2 ** t)
        for g in self.groups:
            for p in g["params"]:
                if p.grad is None:
                    continue
                shape = (self.restarts,) + (1,) * (p.dim() - 1)
                on = active.reshape(shape)
                grad = torch.where(on, p.grad, torch.zeros((), dtype=p.dtype, device=p.device))
                m, v = self.state[id(p)]
                m.copy_(torch.where(on, m * b1 + grad * (1 - b1), m))
                v.copy_(torch.where(on, v * b2 + grad * grad * (1 - b2), v))
                step_size = (g["lr"] * self.lr_mult / bc1).reshape(shape)
                denom = (v.sqrt() / bc2_sqrt.reshape(shape)) + self.eps
                p.sub_(torch.where(on, step_size * m / denom, torch.zeros((), dtype=p.dtype, device=p.device)))
