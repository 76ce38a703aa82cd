"""The latent loss: physics-prediction error plus the KL term that stops the encoder collapsing."""
from __future__ import annotations

import torch


def kl_to_prior(z: torch.Tensor, mean: float = 0.0, std: float = 1.0) -> torch.Tensor:
    """KL( N(mu_z, sigma_z^2) || N(mean, std^2) ) summed over latent dimensions.

    mu_z and sigma_z^2 are the batch mean and variance of each latent dimension; z is (N, d), or
    (R, N, d) for R restarts, which gives one KL per restart.
    """
    mu = z.mean(dim=-2)
    var = z.var(dim=-2, unbiased=False).clamp_min(1e-12)
    prior_var = std * std
    kl = 0.5 * (torch.log(prior_var / var) + (var + (mu - mean) ** 2) / prior_var - 1.0)
    return kl.sum(dim=-1)


def restart_losses(z_win: torch.Tensor, z_pred: torch.Tensor, first: int, *, prior: tuple[float, float] = (0.0, 1.0),
                   use_kl: bool = True) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(total, mse, kl), each (R,), for encoded windows and predictions (R, B, L, d).

    The MSE is over the predicted frames (from `first` on); the KL over every latent in the
    windows, so per-frame and per-window encoding of the same batch give the same loss.
    """
    mse = (z_win[:, :, first:] - z_pred[:, :, first:]).pow(2).mean(dim=(1, 2, 3))
    kl = kl_to_prior(z_win.reshape(z_win.shape[0], -1, z_win.shape[-1]), *prior)
    return (mse + kl if use_kl else mse), mse, kl


def latent_loss(z_win: torch.Tensor, z_pred: torch.Tensor, n_context: int, *, prior: tuple[float, float] = (0.0, 1.0),
                use_kl: bool = True) -> tuple[torch.Tensor, dict[str, float]]:
    """The loss of one run's windows (B, L, d): restart_losses with a single restart."""
    total, mse, kl = restart_losses(z_win[None], z_pred[None], n_context, prior=prior, use_kl=use_kl)
    return total[0], {"mse": float(mse[0].detach()), "kl": float(kl[0].detach())}
