"""Frame -> latent state encoders. The paper's MLP is the default; a small CNN is an option.

Each encoder maps (N, C, H, W) float frames to (N, d) latents with no output activation, so the
latent can take any sign and scale the prior asks for.
"""
from __future__ import annotations

import torch
from torch import nn


class LinearEncoder(nn.Module):
    """An affine map of the frame: the latent is a weighted sum of pixels.

    It cannot bend the latent, which matters for equations whose solutions map onto solutions
    of the same equation with other constants under a nonlinear change of variable: if
    z' = -gamma*z then w = z**p obeys w' = -p*gamma*w, so an MLP can report any decay rate.
    """

    def __init__(self, in_shape: tuple[int, int, int], dim: int):
        super().__init__()
        n_in = in_shape[0] * in_shape[1] * in_shape[2]
        self.net = nn.Sequential(nn.Flatten(), nn.Linear(n_in, dim))
        nn.init.normal_(self.net[1].weight, std=n_in ** -0.5)
        nn.init.zeros_(self.net[1].bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class MLPEncoder(nn.Module):
    """The paper's encoder: three linear layers with ReLU between them, Kaiming init."""

    def __init__(self, in_shape: tuple[int, int, int], dim: int, hidden: int = 200):
        super().__init__()
        n_in = in_shape[0] * in_shape[1] * in_shape[2]
        self.net = nn.Sequential(
            nn.Flatten(),
            nn.Linear(n_in, hidden), nn.ReLU(),
            nn.Linear(hidden, hidden), nn.ReLU(),
            nn.Linear(hidden, dim),
        )
        for m in self.net:
            if isinstance(m, nn.Linear):
                nn.init.kaiming_normal_(m.weight, nonlinearity="relu")
                nn.init.zeros_(m.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class CNNEncoder(nn.Module):
    """A small strided CNN for larger frames where the MLP's first layer would be huge."""

    def __init__(self, in_shape: tuple[int, int, int], dim: int, width: int = 16, hidden: int = 64):
        super().__init__()
        c = in_shape[0]
        self.features = nn.Sequential(
            nn.Conv2d(c, width, 5, stride=2, padding=2), nn.ReLU(),
            nn.Conv2d(width, 2 * width, 5, stride=2, padding=2), nn.ReLU(),
            nn.Conv2d(2 * width, 2 * width, 3, stride=2, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool2d((4, 4)), nn.Flatten(),
        )
        self.head = nn.Sequential(nn.Linear(2 * width * 16, hidden), nn.ReLU(), nn.Linear(hidden, dim))
        for m in self.modules():
            if isinstance(m, (nn.Linear, nn.Conv2d)):
                nn.init.kaiming_normal_(m.weight, nonlinearity="relu")
                nn.init.zeros_(m.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x))


ENCODERS = {"mlp": MLPEncoder, "cnn": CNNEncoder, "linear": LinearEncoder}


def make_encoder(name: str, in_shape: tuple[int, int, int], dim: int) -> nn.Module:
    try:
        return ENCODERS[name](in_shape, dim)
    except KeyError:
        raise ValueError(f"unknown encoder {name!r}; choose one of {', '.join(ENCODERS)}") from None


def normalise_frames(frames: torch.Tensor) -> torch.Tensor:
    """Per-video normalisation: remove the mean image, divide by the global standard deviation.

    Removing the mean image leaves only what changes, so a static background costs the encoder
    nothing; one global scale (not per pixel) keeps the relative size of changes between pixels.
    """
    centred = frames - frames.mean(dim=0, keepdim=True)
    return centred / centred.std().clamp_min(1e-8)
