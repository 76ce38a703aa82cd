"""Units carried: a constant's unit from its states' units and seconds; the scale stick."""
import math

import numpy as np
import pytest
import torch

from fitode.eqparse import parse
from fitode.eqparse.units import constant_units, format_unit, time_exponents
from fitode.errors import ConfigError
from fitode.scale import parse_scale
from fitode.train.observe import Track, resolve_observation
from fitode.train.observe.base import Lengths


@pytest.mark.parametrize("eq, free, want", [
    ("y'' = -g", ["g"], {"g": "px/s^2"}),
    ("h' = -k*sqrt(h)", [], {"k": "px^0.5/s"}),
    ("y'' = -g - k*y'*abs(y')", ["g"], {"g": "px/s^2", "k": "1/px"}),
    ("x'' = -w2*x - c*x'", [], {"w2": "1/s^2", "c": "1/s"}),
    ("x'' = 0; y'' = -g", ["g"], {"g": "px/s^2"}),
])
def test_a_constant_is_in_units_of_its_states_and_seconds(eq, free, want):
    system = parse(eq, free=free)
    assert constant_units(system, {s: "px" for s in system.states}) == want


def test_a_fixed_constant_with_units_of_its_own_leaves_the_units_to_the_equation_file():
    system = parse("x'' = -g/L*sin(x)")  # g fixed in m/s^2: L's unit is not built from x's alone
    assert constant_units(system, {"x": "rad"}) == {"L": None}
    assert time_exponents(parse("s'' = a"))["a"] == 2.0


def test_format_unit():
    assert format_unit({"m": 1, "s": -2}) == "m/s^2"
    assert format_unit({"m": 0.5, "s": -1}) == "m^0.5/s"
    assert format_unit({"s": -1}) == "1/s"
    assert format_unit({"px": 1, "s": 1}) == "px*s"


def test_scale_stick_text_and_uncertainty():
    stick = parse_scale("10,20,410,20=1.0±0.01")
    assert stick.pixels == 400 and stick.metres_per_px == pytest.approx(0.0025)
    # the distance's 1% and each end's pixel (sqrt(2)/400 of the length), in quadrature
    assert stick.relative_std == pytest.approx(math.hypot(0.01, math.sqrt(2) / 400))
    assert parse_scale("10,20,410,20+-0.5=1.0").end_std == 0.5
    assert parse_scale(((0, 0), (300, 400), (2.5, 0.01))).metres_per_px == pytest.approx(0.005)
    for bad in ("1,2,3=4", "1,2,3,x=1", "1,2,3,4=-1", "1,2,1,2=1", "1,2,3,4"):
        with pytest.raises(ConfigError, match="--scale"):
            parse_scale(bad)
    with pytest.raises(ConfigError, match="outside the source frame"):
        stick.check_inside((400, 300))


def test_a_measured_position_carries_its_unit_in_source_pixels_or_metres():
    t = np.arange(60) / 240
    throw = np.column_stack([50 + 900 * t, 200 - 300 * t + 0.5 * 2400 * t ** 2])  # source pixels, y down
    system = parse("y'' = -g", free=["g"])
    model = resolve_observation("position", system, track=Track(throw, 5.0, 1, "generated"))
    model.use_lengths(Lengths((2.0, 2.0)))  # the reader's track is in source pixels: the shrink does not apply
    prepared = model.prepare(torch.zeros(len(t), 1, 8, 8))
    z = prepared.inputs.reshape(-1).numpy() * prepared.unit_scale[0]
    assert prepared.units == ("px",)
    np.testing.assert_allclose(z, -(throw[:, 1] - throw[:, 1].mean()), atol=1e-3)  # px, up
    model.use_lengths(Lengths((2.0, 2.0), metres_per_px=0.004))
    metres = model.prepare(torch.zeros(len(t), 1, 8, 8))
    assert metres.units == ("m",) and metres.unit_scale[0] == pytest.approx(0.004 * prepared.unit_scale[0])
    # the note says what the track is: the change's centroid, or the object followed by its look
    assert "the centroid of what differs most from the static scene" in prepared.note
    followed = resolve_observation("position", system, track=Track(throw, 5.0, 1, "generated", followed=True))
    note = followed.prepare(torch.zeros(len(t), 1, 8, 8)).note
    assert "the object followed by its appearance (5 pixels)" in note and "centroid" not in note


def test_lengths_on_shrunk_frames_are_in_source_pixels():
    lengths = Lengths((4.0, 2.0))
    assert lengths.factor((1.0, 0.0)) == 4.0 and lengths.factor((0.0, 1.0)) == 2.0
    assert lengths.factor((1.0, 1.0)) == pytest.approx(math.sqrt(10))  # along a diagonal of the frames
    assert lengths.factor((1.0, 0.0), source=True) == 1.0
    assert Lengths(metres_per_px=0.01).factor((0.0, 1.0)) == pytest.approx(0.01) and Lengths(metres_per_px=0.01).unit == "m"


def test_a_short_tracked_motion_named_along_an_axis_is_a_measured_length(monkeypatch):
    # a cart's last flight alone: 27 pixels up and back, less than the change's size in the shrunk
    # frames (the cart and its ghost in the median), while the tracked cart travels 5 times its own
    # size: auto measures it (it was the paper's free encoder, "latent units", a scale stick dropped)
    import fitode.train.observe.auto as auto
    from fitode.report import length_lines
    monkeypatch.setattr(auto, "look", lambda frames, track=None: auto.Look(6.0, 9.0, 0.1, followed=5.4))
    frames = torch.zeros(40, 1, 8, 8)
    chosen = resolve_observation(None, parse("x'' = -a"), frames)
    assert chosen.name == "position" and "the tracked object moves 5.4x its own size" in chosen.reason
    # a state named for no image axis stays the paper's free encoder, and a scale it cannot use is
    # said, not dropped silently
    plain = resolve_observation(None, parse("q'' = -a"), frames)
    assert plain.name == "any"
    plain.use_lengths(Lengths(metres_per_px=0.003))
    assert length_lines(plain) and "--scale is not used" in length_lines(plain)[0]
    monkeypatch.setattr(auto, "look", lambda frames, track=None: auto.Look(6.0, 9.0, 0.1, followed=0.5))
    assert resolve_observation(None, parse("x'' = -a"), frames).name == "any"  # the object barely moves
