"""Frame -> latent state encoders. The paper's MLP is the default; a small CNN is an option.

Each encoder maps (N, C, H, W) float frames to (N, d) latents with no output activation, so the
latent can take any sign and scale the prior asks for.
"""
from __future__ import annotations

import torch
from torch import nn
from torch.func import functional_call, stack_module_state, vmap

from fitode.errors import ConfigError

from .config import ENCODER_NAMES


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
assert tuple(ENCODERS) == ENCODER_NAMES, "train/config.py lists the encoders the CLI offers"


def make_encoder(name: str, in_shape: tuple[int, int, int], dim: int, *, output_mean: float = 0.0) -> nn.Module:
    """An encoder by name; its output bias starts at the prior's mean, so that a latent that must
    stay positive (sqrt(h) under the prior N(1, 0.2)) is positive from the first step."""
    if name not in ENCODERS:
        raise ConfigError(f"unknown encoder {name!r}; choose one of {', '.join(ENCODERS)}")
    enc = ENCODERS[name](in_shape, dim)
    last = [m for m in enc.modules() if isinstance(m, nn.Linear)][-1]
    with torch.no_grad():
        last.bias.fill_(output_mean)
    return enc


class BatchedEncoder(nn.Module):
    """R encoders of one architecture as one module: (N, C, H, W) -> (R, N, d).

    The R modules' weights are stacked along a leading axis (torch.func.stack_module_state) and
    applied with vmap, so one call runs every restart's encoder as batched matrix products
    instead of R separate small ones. Restart r starts from exactly the weights a lone
    make_encoder would draw after torch.manual_seed(seeds[r]).
    """

    def __init__(self, name: str, in_shape: tuple[int, int, int], dim: int, seeds, *, output_mean: float = 0.0):
        super().__init__()
        modules = []
        for seed in seeds:
            torch.manual_seed(int(seed))
            modules.append(make_encoder(name, in_shape, dim, output_mean=output_mean))
        params, _ = stack_module_state(modules)  # the encoders have no buffers
        self._names = list(params)
        self.weights = nn.ParameterList([nn.Parameter(params[n].detach().clone()) for n in self._names])
        self._base = [modules[0].to("meta")]  # a list: the skeleton is not a submodule (no weights of its own)
        self.restarts = len(modules)
        self._layers = _dense_layers(modules[0], self._names)

    def forward(self, x: torch.Tensor, restarts: torch.Tensor | None = None) -> torch.Tensor:
        """(N, C, H, W) -> (R, N, d); with `restarts` (indices), only those restarts' encoders run,
        (len(restarts), N, d): the training loop leaves out the restarts that have stopped."""
        weights = tuple(self.weights) if restarts is None else tuple(w[restarts] for w in self.weights)
        if self._layers is not None:
            return self._dense(x, weights)
        base = self._base[0]

        def one(params, inp):
            return functional_call(base, dict(zip(self._names, params)), (inp,))
        return vmap(one, in_dims=(0, None))(weights, x)

    def _dense(self, x: torch.Tensor, weights: tuple[torch.Tensor, ...]) -> torch.Tensor:
        """The MLP and linear encoders as a chain of batched matrix products: the same numbers as
        the vmap path, at a third of its cost per step (vmap's per-call overhead dominates these
        small layers; bench/speed.py)."""
        h = x.flatten(1).expand(weights[0].shape[0], -1, -1)  # every restart reads the same frames
        for layer in self._layers:
            if layer is None:
                h = torch.relu(h)
            else:
                w, b = weights[layer[0]], weights[layer[1]]
                h = torch.baddbmm(b[:, None, :], h, w.transpose(1, 2))
        return h

    def single(self, r: int) -> nn.Module:
        """Restart r's encoder as an ordinary module (for saving or inspection)."""
        import copy
        mod = copy.deepcopy(self._base[0]).to_empty(device=self.weights[0].device)
        mod.load_state_dict({n: w[r].detach() for n, w in zip(self._names, self.weights)})
        return mod


def _dense_layers(module: nn.Module, names: list[str]) -> list[tuple[int, int] | None] | None:
    """For an encoder that is one Sequential of Flatten, Linear and ReLU (MLP, linear): its layers
    as (weight, bias) positions in `names`, None for a ReLU. None for any other architecture."""
    net = getattr(module, "net", None)
    if type(module) not in (MLPEncoder, LinearEncoder) or not isinstance(net, nn.Sequential):
        return None
    layers: list[tuple[int, int] | None] = []
    for i, m in enumerate(net):
        if isinstance(m, nn.Linear):
            layers.append((names.index(f"net.{i}.weight"), names.index(f"net.{i}.bias")))
        elif isinstance(m, nn.ReLU):
            layers.append(None)
        elif not isinstance(m, nn.Flatten):
            return None
    return layers


class FixedReadout(nn.Module):
    """R restarts that read their inputs (N, k, 1, 1) as the latent itself, (R, N, k), with no
    weights: a state measured in its own units, which no encoder may rescale."""

    def __init__(self, restarts: int, in_shape: tuple[int, int, int], dim: int):
        super().__init__()
        columns = in_shape[0] * in_shape[1] * in_shape[2]
        if columns != dim:
            raise ConfigError(f"a latent in the state's own units reads one measured column per state: "
                              f"{columns} column{'s' if columns != 1 else ''} for {dim} state{'s' if dim != 1 else ''}")
        self.restarts = restarts

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = x.reshape(x.shape[0], -1)
        return z[None].expand(self.restarts, *z.shape)


def normalise_frames(frames: torch.Tensor) -> torch.Tensor:
    """Per-video normalisation: remove the mean image, divide by the global standard deviation.

    Removing the mean image leaves only what changes, so a static background costs the encoder
    nothing; one global scale (not per pixel) keeps the relative size of changes between pixels.
    """
    centred = frames - frames.mean(dim=0, keepdim=True)
    return centred / centred.std().clamp_min(1e-8)
