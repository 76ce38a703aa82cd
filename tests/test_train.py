"""Trainer pieces: windows, loss, per-frame against per-window encoding, restarts, NaN guard."""
import math

import numpy as np
import pytest
import sympy
import torch

from fitode.codegen import PhysicsBlock
from fitode.eqparse import OdeSystem, ParamSpec, deriv_symbol
from fitode.train.encoders import MLPEncoder, CNNEncoder, normalise_frames
from fitode.train.loss import kl_to_prior, latent_loss
from fitode.train.trainer import TrainConfig, fit_frames, restart_inits, select_runs
from fitode.train.result import FitResult, RunRecord
from fitode.train.windows import Windows, distinct_frames


def oscillator() -> OdeSystem:
    z, z1 = deriv_symbol("z", 0), deriv_symbol("z", 1)
    g0, g1 = sympy.symbols("g0 g1")
    return OdeSystem(states=("z",), orders={"z": 2}, rhs={"z": -g1 * z1 - g0 * z},
                     learnable=("g0", "g1"), text="z'' + g1*z' + g0*z = 0")


def test_windows_index_and_distinct_frames():
    w = Windows(10, 4)
    assert w.count == 7
    idx = w.index(torch.tensor([0, 3, 6]))
    assert idx.tolist() == [[0, 1, 2, 3], [3, 4, 5, 6], [6, 7, 8, 9]]
    frames, inverse = distinct_frames(idx)
    assert frames.tolist() == list(range(10))
    assert torch.equal(frames[inverse], idx)
    # a sparse batch encodes only the frames it touches
    frames, inverse = distinct_frames(w.index(torch.tensor([0, 6])))
    assert frames.tolist() == [0, 1, 2, 3, 6, 7, 8, 9]


def test_kl_is_zero_at_prior_and_positive_elsewhere():
    z = torch.randn(100000, 2, generator=torch.Generator().manual_seed(0))
    assert float(kl_to_prior(z)) < 1e-3
    assert float(kl_to_prior(z * 0.1)) > 1.0
    assert float(kl_to_prior(z + 3.0)) > 4.0
    assert float(kl_to_prior(1 + 0.2 * z, mean=1.0, std=0.2)) < 1e-3


def test_encoders_shape():
    x = torch.randn(5, 1, 32, 40)
    assert MLPEncoder((1, 32, 40), 2)(x).shape == (5, 2)
    assert CNNEncoder((1, 32, 40), 3)(x).shape == (5, 3)


def test_normalise_removes_static_background():
    t = torch.linspace(0, 1, 50)
    frames = torch.full((50, 1, 8, 8), 0.7)
    frames[:, 0, 2, 2] += t
    x = normalise_frames(frames)
    assert x[:, 0, 0, 0].abs().max() < 1e-5
    assert x[:, 0, 2, 2].std() > 1.0


def test_per_frame_encoding_equals_per_window_encoding():
    torch.manual_seed(0)
    system = oscillator()
    frames = torch.randn(60, 1, 12, 12)
    L = 20
    w = Windows(60, L)
    encoder = MLPEncoder((1, 12, 12), 1)
    block = PhysicsBlock(system, {"g0": ParamSpec(init=3.0), "g1": ParamSpec(init=0.1)})
    starts = torch.tensor([0, 5, 17, 40])
    idx = w.index(starts)
    # per window: every frame encoded once per window that holds it (the official code)
    z_win_a = encoder(frames[idx.reshape(-1)]).reshape(len(starts), L, 1)
    # per frame: each distinct frame once, windows gathered
    ids, inv = distinct_frames(idx)
    z_win_b = encoder(frames[ids])[inv]
    nc = block.n_context
    la, _ = latent_loss(z_win_a, block(z_win_a[:, :nc], L, 0.2), nc)
    lb, _ = latent_loss(z_win_b, block(z_win_b[:, :nc], L, 0.2), nc)
    assert torch.allclose(la, lb, rtol=1e-5, atol=1e-6)
    ga = torch.autograd.grad(la, list(encoder.parameters()))
    gb = torch.autograd.grad(lb, list(encoder.parameters()))
    for a, b in zip(ga, gb):
        assert torch.allclose(a, b, rtol=1e-4, atol=1e-6)


def test_restart_inits_spread_and_bounds():
    system = oscillator()
    params = {"g0": ParamSpec(init=1.0), "g1": ParamSpec(init=0.5, min=0.0)}
    inits = restart_inits(system, params, 7, seed=0)
    assert inits[0] == {"g0": 1.0, "g1": 0.5}
    assert all(-10 <= r["g0"] <= 10 for r in inits)
    assert all(r["g1"] > 0 for r in inits)
    assert len({r["g0"] for r in inits}) == 7
    # the user's start is one candidate (run 0), not every run's
    user = restart_inits(system, params, 4, seed=1, fixed_init={"g0": 2.5})
    assert user[0] == {"g0": 2.5, "g1": 0.5} and all(r["g0"] != 2.5 for r in user[1:])


def test_select_runs_excludes_failed_and_high_loss():
    def rec(i, loss, status="ok"):
        return RunRecord(index=i, seed=i, init={}, final={}, loss=loss, steps=1, status=status)
    runs = [rec(0, 0.10), rec(1, 0.12), rec(2, 5.0), rec(3, math.nan, "failed")]
    assert select_runs(runs, 1.5) == [0, 1]
