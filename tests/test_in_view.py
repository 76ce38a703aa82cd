"""An object that enters or leaves the view: the clip is read where it is whole in view
(fitode.pipeline.in_view, view_span) and its pieces start and end there (train/pieces.py)."""
import json

import numpy as np
import pytest

from fitode.pipeline import UNSEEN_MAX, view_span
from fitode.train.observe.track import Track
from fitode.train.pieces import find_pieces

from test_pieces import parabola_fit

BOX = (0, 0, 320, 180)


def crossing(n=150, v=250.0 / 60, x0=-20.0, stray=(86, 90, 95, 96, 97, 98, 130, 132)):
    """A puck's track (source pixels) crossing a 320-wide view left to right: unseen before it
    comes in and after it has gone, but for flickers of noise after (at a ruler's edge: a few
    frames apart, nearer each other in time than the gaps between them are long)."""
    x = x0 + v * np.arange(n)
    xy = np.column_stack([x, 90 + 0.05 * x])
    xy[(x < -8) | (x > 328)] = np.nan  # a disc 8.5 px in radius is seen while part of it is in view
    for i in stray:
        xy[i] = (200.0, 60.0)
    return Track(xy, 227.0, 1, "generated")


def test_the_span_is_where_the_object_is_whole_in_view_without_the_flickers_after_it_left():
    track = crossing()
    x = track.xy[:, 0]
    a, b = view_span(track, BOX)
    assert track.unseen > UNSEEN_MAX * len(track)
    # whole in view: its centre at least its radius (9.5 px with the margin) inside the frame
    assert x[a] >= 9 and x[a - 1] < 9.5
    assert x[b - 1] <= 310.5 and (np.isnan(x[b]) or x[b] > 310)
    assert b <= 83  # the flickers are not the object
    # an end the user chose stays theirs
    assert view_span(track, BOX, start_given=True)[0] == 0
    # (to the user's end it is unseen in half the frames: nothing to cut that helps, the observation says so)
    assert view_span(track, BOX, end_given=True) is None


def test_no_span_where_the_object_is_in_view_enough_or_lost_in_the_middle():
    seen = crossing(n=80, v=300.0 / 80, x0=10.0, stray=())
    assert view_span(seen, BOX) is None  # whole in view throughout
    holes = crossing(stray=())
    holes.xy[40:60] = np.nan  # lost for 20 frames in the middle of its 70 in view: the observation's to say
    assert view_span(holes, BOX) is None
    short = crossing(n=150, v=1500.0 / 60, stray=())  # in view for 13 frames: too few to fit
    assert view_span(short, BOX) is None


def test_an_object_that_comes_in_and_stops_in_view_is_cut_where_it_came_in_and_one_still_is_not():
    # a puck sliding in from the left edge, slowing to rest in the middle: unseen in 3 frames only
    t = np.arange(150) / 60
    x = -20 + 300 * np.minimum(t, 1.5) - 100 * np.minimum(t, 1.5) ** 2
    xy = np.column_stack([x, 90 + 0.05 * x])
    xy[x < -8] = np.nan
    xy[1] = (208.0, 95.0)  # a flicker of noise where it will come to rest
    a, b = view_span(Track(xy, 227.0, 1, "generated"), BOX)
    assert b == 150 and x[a] >= 9 and x[a - 1] < 9.5
    # a ball unseen at first because it hangs still in the middle, merged into the static scene,
    # then swinging: it does not enter the view there
    swing = np.column_stack([160 + 40 * np.sin(np.arange(150) / 9.0), np.full(150, 90.0)])
    swing[:20] = np.nan
    assert view_span(Track(swing, 227.0, 1, "generated"), BOX) is None


def test_pieces_of_an_object_that_enters_and_leaves_are_no_hold_and_no_stop():
    dt = 1 / 60
    t = np.arange(80) * dt
    x = 250.0 * t - 0.5 * 90.0 * t ** 2 + np.random.default_rng(0).normal(0, 0.1, 80)
    # the edge frames are cut already; a slow first frame must not read as a hold, released
    x[0] = x[1]
    fit = parabola_fit(x)
    pieces = find_pieces(x[:, None], dt, fit, enters=True, leaves=True)
    kinds = [e.kind for e in pieces.events]
    assert kinds[0] == "enter" and kinds[-1] == "gone" and "release" not in kinds and "stop" not in kinds
    words = pieces.describe(dt, n_frames=80)
    assert words.startswith("enters the view; ") and "leaves the view at" in words and "held" not in words
    before = find_pieces(x[:, None], dt, fit)  # unsaid, the same path's first frames are a hold
    assert "enter" not in [e.kind for e in before.events]


@pytest.mark.slow
def test_a_puck_that_crosses_the_view_gives_its_speed_with_no_start_or_end(tmp_path):
    # before: "the position observation sees no change from the median frame in 65 of 150 frames
    # ...; trim the clip to the motion (--start/--end)"
    import fitode
    from fitode.pipeline import run_video, ReadOptions

    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:90, 0:160]
    ground = 120 + 30 * np.sin(xx / 9.0) * np.cos(yy / 11.0)
    frames = []
    for i in range(110):
        x = -10 + 125.0 * i / 60
        a = np.clip(4.8 - np.hypot(xx - x, yy - 45 - 0.05 * x), 0, 1)
        frames.append(np.clip(ground * (1 - a) + 30 * a + rng.normal(0, 2, ground.shape), 0, 255))
    path = tmp_path / "puck.npy"
    np.save(path, np.stack(frames).astype(np.uint8))
    outcome = run_video(path, tmp_path / "run", read=ReadOptions(fps=60), fit={"eq": "x' = v"}, log=None,
                        plots=False)
    v = outcome.result.parameters["v"]
    assert v.value == pytest.approx(125.0, rel=0.01)
    assert v.interval[0] <= 125.0 <= v.interval[1] and outcome.result.verdicts["v"]["verdict"] == "trusted"
    report = json.loads((tmp_path / "run" / "result.json").read_text())
    assert any("enters and leaves the view" in n and "frames outside" in n for n in report["input"]["notes"])
    pieces = outcome.result.meta["pieces"]["summary"]
    assert pieces.startswith("enters the view") and "leaves the view" in pieces
    # the library's front door reads the same frames
    assert fitode.fit(str(path), eq="x' = v", fps=60).parameters["v"].value == pytest.approx(v.value, rel=1e-9)
