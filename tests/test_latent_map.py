"""The learnable latent-to-state map x = s*z + b (train/latent_map.py), one (s, b) per restart."""
from __future__ import annotations

import math

import pytest
import torch

from fitode.eqparse import parse
from fitode.eqparse.gauge import StateGauge, gauge_plan
from fitode.train.latent_map import SCALE_START, Gauge


def _plan(scale: bool, offset: bool, positive: bool = False) -> dict[str, StateGauge]:
    return {"x": StateGauge("x", scale, offset, positive, "test")}


def test_to_latent_inverts_to_state_for_every_restart():
    gauge = Gauge(_plan(True, True), ["x"], restarts=3, prior=(0.0, 1.0))
    with torch.no_grad():
        gauge.log_scale.copy_(torch.tensor([[0.3], [-1.0], [2.0]]))
        gauge.offset.copy_(torch.tensor([[0.5], [-2.0], [0.0]]))
    z = torch.randn(3, 5, 7, 1)
    x = gauge.to_state(z)
    s, b = gauge.scale_offset()
    assert torch.allclose(x[1], z[1] * math.exp(-1.0) - 2.0, atol=1e-6)
    assert torch.allclose(gauge.to_latent(x), z, atol=1e-5)
    assert torch.allclose(s[:, 0], torch.tensor([0.3, -1.0, 2.0]).exp())


def test_fixed_parts_stay_identity_whatever_their_parameters_hold():
    gauge = Gauge(_plan(False, False), ["x"], restarts=2, prior=(0.0, 1.0))
    with torch.no_grad():  # what a stray optimiser step could do: the map must ignore it
        gauge.log_scale.add_(1.0)
        gauge.offset.add_(1.0)
    z = torch.randn(2, 4, 1)
    assert torch.equal(gauge.to_state(z), z)
    assert not gauge.learned
    # and gradients do not reach the fixed parameters
    gauge.to_state(z.requires_grad_()).sum().backward()
    assert gauge.log_scale.grad is None or torch.all(gauge.log_scale.grad == 0)


def test_a_learned_scale_starts_small_and_disabled_means_identity():
    learned = Gauge(_plan(True, False), ["x"], restarts=2, prior=(0.0, 1.0))
    s, b = learned.scale_offset()
    assert torch.allclose(s, torch.full((2, 1), SCALE_START)) and torch.all(b == 0)
    off = Gauge(_plan(True, True), ["x"], restarts=2, prior=(0.0, 1.0), enabled=False)
    s, b = off.scale_offset()
    assert torch.all(s == 1) and torch.all(b == 0) and not off.learned


def test_enter_domain_lifts_a_positive_state_above_zero_and_only_it():
    gauge = Gauge({"h": StateGauge("h", True, True, True, "under sqrt"), "v": StateGauge("v", True, True, False, "")},
                  ["h", "v"], restarts=2, prior=(0.0, 1.0))
    z = torch.zeros(2, 50, 2)
    z[..., 0] = torch.linspace(-40, 10, 50)  # an untrained encoder spreads far wider than the prior
    z[..., 1] = torch.linspace(-40, 10, 50)
    before = gauge.offset.detach().clone()
    gauge.enter_domain(z)
    x = gauge.to_state(z)
    assert torch.all(x[..., 0] > 0)
    assert torch.equal(gauge.offset[:, 1], before[:, 1])  # v is not under a root: left alone


def test_values_report_each_restart_and_the_plan_comes_from_the_equation():
    system = parse("h' = -k*sqrt(h)")
    plan = gauge_plan(system)
    gauge = Gauge(plan, system.states, restarts=2, prior=(1.0, 0.2))
    # under sqrt, h's zero is learned and starts inside the domain: three prior spreads up, s fixed at 1
    assert plan["h"].positive and plan["h"].offset_learned and not plan["h"].scale_learned
    v = gauge.values(1)
    assert set(v) == {"h"} and v["h"]["scale"] == 1.0
    assert math.isclose(v["h"]["offset"], 3 * 0.2, rel_tol=1e-6)
    with pytest.raises(KeyError):
        Gauge({}, ["h"], restarts=1, prior=(0.0, 1.0))


def test_some_restarts_map_with_their_own_scale_and_offset():
    gauge = Gauge(_plan(True, True), ["x"], restarts=3, prior=(0.0, 1.0))
    with torch.no_grad():
        gauge.log_scale.copy_(torch.tensor([[0.1], [0.2], [0.3]]))
        gauge.offset.copy_(torch.tensor([[1.0], [2.0], [3.0]]))
    z = torch.randn(3, 6, 1)
    some = torch.tensor([0, 2])
    torch.testing.assert_close(gauge.to_state(z[some], some), gauge.to_state(z)[some], rtol=0, atol=0)
    torch.testing.assert_close(gauge.to_latent(z[some], some), gauge.to_latent(z)[some], rtol=0, atol=0)
