"""The encoders (train/encoders.py): R restarts' encoders as one batched module."""
from __future__ import annotations

import pytest
import torch

from fitode.train.encoders import BatchedEncoder, make_encoder


@pytest.mark.parametrize("name", ["mlp", "linear", "cnn"])
def test_each_restart_is_the_lone_encoder_its_seed_draws_and_some_run_alone(name):
    shape = (1, 12, 12)
    enc = BatchedEncoder(name, shape, 1, seeds=[3, 4, 5])
    x = torch.randn(7, *shape)
    whole = enc(x)
    assert whole.shape == (3, 7, 1)
    torch.manual_seed(4)
    lone = make_encoder(name, shape, 1)
    torch.testing.assert_close(whole[1], lone(x), rtol=1e-5, atol=1e-5)
    some = torch.tensor([0, 2])
    # the training loop runs only the restarts still training: their rows, the same numbers
    torch.testing.assert_close(enc(x, restarts=some), whole[some], rtol=0, atol=1e-6)
    enc(x, restarts=some).sum().backward()
    assert torch.all(enc.weights[0].grad[1] == 0) and torch.any(enc.weights[0].grad[0] != 0)
