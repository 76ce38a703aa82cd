"""The latent loss: physics-prediction error plus the KL term that stops the encoder collapsing."""
from __future__ import annotations

import torch


def kl_to_prior(z: torch.Tensor, mean: float = 0.0, std: float = 1.0) -> torch.Tensor:
    """KL( N(mu_z, sigma_z^2) || N(mean, std^2) ) summed over latent dimensions.

    mu_z and sigma_z^2 are the batch mean and variance of each latent dimension (z: (N, d)).
    """
    mu = z.mean(dim=0)
    var = z.var(dim=0, unbiased=False).clamp_min(1e-12)
    prior_var = std * std
    kl = 0.5 * (torch.log(prior_var / var) + (var + (mu - mean) ** 2) / prior_var - 1.0)
    return kl.sum()


def latent_loss(z_win: torch.Tensor, z_pred: torch.Tensor, n_context: int, *, prior: tuple[float, float] = (0.0, 1.0),
                use_kl: bool = True) -> tuple[torch.Tensor, dict[str, float]]:
    """MSE between encoded windows (B, L, d) and physics predictions on frames n_context.., plus KL.

    The KL is taken over every latent in the windows, so per-frame and per-window encoding of the
    same batch give the same loss.
    """
    mse = torch.mean((z_win[:, n_context:] - z_pred[:, n_context:]) ** 2)
    kl = kl_to_prior(z_win.reshape(-1, z_win.shape[-1]), *prior)
    total = mse + kl if use_kl else mse
    return total, {"mse": float(mse.detach()), "kl": float(kl.detach())}
