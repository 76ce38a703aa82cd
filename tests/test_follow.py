"""The object tracker (fitode.video.follow): where the object is, and where it is hidden."""
import numpy as np
import pytest

from fitode.synth import render as R
from fitode.video.follow import choose, follow_best, scatter, switches
from fitode.video.track import MAX_OBJECTS, measure_paths


def _clip(n=60, h=120, w=160, cover=None, seed=0, walker=False):
    """A striped ball swinging across a textured wall (gray uint8 frames) and its true centre per
    frame (pixel (0, 0)'s centre at (0, 0)); cover: frames in which a dark bar stands over it;
    walker: two dark legs walking back and forth behind it (more change than the ball)."""
    rng = np.random.default_rng(seed)
    wall = (0.6 + 0.05 * R.value_noise(rng, h, w, (4, 12))).astype(np.float32)
    t = np.arange(n) / 30.0
    cx = w / 2 + 40 * np.cos(2.5 * t)
    cy = h / 2 + 10 * np.sin(2.5 * t) ** 2
    frames = np.empty((n, h, w), np.uint8)
    for i in range(n):
        cv = R.Canvas(wall.copy(), 4)
        if walker:  # two legs, each swinging about the hip as they walk: their shape changes
            hip = w * (0.1 + 0.8 * abs(((i / 40.0) % 2) - 1))
            for k in (0, 1):
                foot = hip + 12 * np.sin(2 * np.pi * i / 15 + np.pi * k)
                cv.paint(R.segment(hip, 0.3 * h, foot, h, 6.0), 0.08, (min(hip, foot) - 8, 0.3 * h - 8, max(hip, foot) + 8, h))
        x, y = cx[i], cy[i]
        cv.paint(R.circle(x, y, 9.0), lambda xx, yy: 0.25 + 0.2 * (np.sin((xx - x) * 0.9) > 0), (x - 10, y - 10, x + 10, y + 10))
        if cover is not None and cover[0] <= i < cover[1]:
            cv.paint(R.box(x, h / 2, 14, h / 2), 0.05, (x - 15, 0, x + 15, h))
        noisy = cv.image + rng.normal(0, 0.01, cv.image.shape)
        frames[i] = np.clip(noisy * 255 + 0.5, 0, 255).astype(np.uint8)
    return frames, np.stack([cx, cy], axis=1) - 0.5


def test_follows_the_object_to_a_fraction_of_a_pixel():
    frames, truth = _clip()
    found = follow_best(frames, measure_paths(frames, MAX_OBJECTS)[0])
    assert found is not None and not found.hidden.any()
    err = np.linalg.norm(found.xy - truth, axis=1)
    assert float(np.sqrt(np.mean(err ** 2))) < 0.3
    assert np.all(found.sigma > 0) and np.all(found.sigma < 1.0)


def test_a_ball_that_stops_dead_is_followed_through_the_stop():
    # a fall that ends at rest: the pass that meets the stop predicts 7 pixels a frame where the
    # ball stands still (or, backwards from the rest, none where it moves 7 pixels a frame)
    n, h, w = 48, 140, 120
    wall = (0.6 + 0.05 * R.value_noise(np.random.default_rng(1), h, w, (4, 12))).astype(np.float32)
    t = np.minimum(np.arange(n), 30) / 30.0
    y = 12 + 105 * t ** 2
    frames = np.empty((n, h, w), np.uint8)
    for i in range(n):
        cv = R.Canvas(wall.copy(), 4)
        cv.paint(R.circle(60.0, y[i], 6.0), lambda xx, yy: 0.25 + 0.2 * (np.sin((xx - 60.0) * 0.9) > 0),
                 (53, y[i] - 7, 67, y[i] + 7))
        frames[i] = np.clip(cv.image * 255 + 0.5, 0, 255).astype(np.uint8)
    found = follow_best(frames, measure_paths(frames, MAX_OBJECTS)[0])
    assert found is not None and not found.hidden.any()
    assert np.abs(found.xy[:, 1] - (y - 0.5)).max() < 0.5


def test_hidden_frames_are_marked_not_filled_with_what_covers_the_object():
    frames, truth = _clip(cover=(20, 26))
    found = follow_best(frames, measure_paths(frames, MAX_OBJECTS)[0])
    assert found is not None
    covered = np.zeros(len(frames), bool)
    covered[20:26] = True
    # every covered frame is hidden, or placed on the object, never on the bar beside it
    err = np.linalg.norm(found.xy - truth, axis=1)
    assert np.all(found.hidden[covered] | (err[covered] < 1.0))
    assert found.hidden[covered].sum() >= 3
    # and the object is taken up again once the bar has passed
    assert np.all(err[~covered] < 0.5)


def test_a_path_that_goes_from_one_moving_thing_to_another_switches():
    t = np.arange(40, dtype=float)
    path = np.stack([50 + 10 * np.sin(0.3 * t), 40 + 0 * t], axis=1)
    area = np.full(40, 100.0)
    assert switches(path, area) == 0  # an object that moves keeps its size
    jumpy, big = path.copy(), area.copy()
    for a, b in ((5, 9), (20, 24)):  # twice to a large thing far away and back
        jumpy[a:b] = (150.0, 90.0)
        big[a:b] = 2000.0
    assert switches(jumpy, big) == 4
    # a large step of the same thing (a fast ball) is no switch, nor a change of size in place
    fast = path.copy()
    fast[10:] += 60.0
    assert switches(fast, area) == 0
    assert switches(path, np.where(t < 20, 100.0, 400.0)) == 0


def test_the_reader_keeps_the_change_detector_where_its_path_does_not_switch_nor_scatter_more():
    frames, truth = _clip()
    paths, areas = measure_paths(frames, MAX_OBJECTS, per_frame=True)
    path, how, found = choose(frames, paths, areas)
    assert found is None
    assert how.startswith("the change from the static scene (its path switches between moving things 0 times")
    assert np.array_equal(path, paths[0], equal_nan=True)
    # the same path with a jitter of a pixel (what a centroid weighed by a changing background does)
    # is the object tracker's to read, once it follows the same ball with less scatter
    rng = np.random.default_rng(3)
    shaky = paths[0] + rng.normal(0.0, 1.0, paths[0].shape)
    path, how, found = choose(frames, np.concatenate([shaky[None], paths[1:]]), areas)
    assert found is not None and "both follow the same object" in how
    assert float(np.sqrt(np.mean(np.linalg.norm(path - truth, axis=1) ** 2))) < 0.3


def test_scatter_is_the_frame_to_frame_noise_about_a_smooth_motion():
    t = np.arange(200) / 60.0
    fall = np.stack([30 + 40 * t, 10 + 0.5 * 900 * t ** 2], axis=1)  # a throw: no third difference
    assert scatter(fall) < 1e-9
    noisy = fall + np.random.default_rng(0).normal(0.0, 0.5, fall.shape)
    assert 0.4 < scatter(noisy) < 0.9  # about the noise's size (a 2-D length, so a little over 0.5)
    noisy[::3] = np.nan  # runs of four placed frames only
    assert np.isnan(scatter(noisy))


def test_the_reader_follows_the_object_where_the_change_detectors_path_switches():
    frames, truth = _clip()
    paths, areas = measure_paths(frames, MAX_OBJECTS, per_frame=True)
    # the strongest change something large far from the ball (legs behind it) but in four short
    # spells, when it is the ball; the ball's own path second
    jumpy, big = np.tile([20.0, 100.0], (len(frames), 1)), 20 * areas
    for a in (8, 22, 36, 50):
        jumpy[a:a + 4], big[a:a + 4] = paths[0][a:a + 4], areas[a:a + 4]
    path, how, found = choose(frames, np.stack([jumpy, paths[0]]), big)
    assert found is not None and path is found.xy
    assert how.startswith("the object followed by its appearance") and "switches between moving things 8 times" in how
    err = np.linalg.norm(path - truth, axis=1)
    assert float(np.sqrt(np.mean(err ** 2))) < 0.3
    # where the detector's path switches but follows the object most of the time, both follow the
    # same thing, and the steadier of the two is taken: here the tracker, whose path never leaves it
    flicker = paths[0].copy()
    for a in (8, 22, 36, 50):
        flicker[a:a + 4] = (20.0, 100.0)
    path, how, found = choose(frames, np.stack([flicker, paths[0]]), np.where(flicker[:, 0] == 20.0, 20 * areas, areas))
    assert found is not None and "both follow the same object" in how
    err = np.linalg.norm(path - truth, axis=1)
    assert float(np.sqrt(np.mean(err ** 2))) < 0.3


@pytest.mark.parametrize("light, dark", [(0.7, 0.3), (0.55, 0.1)])
def test_a_large_object_that_covers_its_own_place_is_read_at_its_centre(light, dark):
    # a printed block a third of the frame wide swinging by less than its width, its light bands the
    # wall's grey or near it: the change from the clip's median frame is a crescent of it, its middle
    # is the wall's colour, and its top and bottom edges stand where the median frame holds the
    # block (they were read 0.8 px off), yet its place is its centre, not the crescent's
    n, h, w = 60, 100, 150
    wall = (0.7 + 0.03 * R.value_noise(np.random.default_rng(2), h, w, (4, 12))).astype(np.float32)
    t = np.arange(n) / 30.0
    cx = w / 2 + 22 * np.cos(2.6 * t)
    cy = 0.55 * h
    frames = np.empty((n, h, w), np.uint8)
    for i in range(n):
        cv = R.Canvas(wall.copy(), 4)
        x = cx[i]

        def body(xx, yy, x=x):
            band = np.sin(3 * np.pi * (xx - x) / 25 + 2 * (yy - cy) / 18) > 0
            edge = np.minimum(25 - np.abs(xx - x), 18 - np.abs(yy - cy)) < 3.0
            return np.where(edge, 0.25, np.where(band, light, dark))
        cv.paint(R.box(x, cy, 25, 18, radius=2), body, (x - 27, cy - 20, x + 27, cy + 20))
        frames[i] = np.clip(cv.image * 255 + 0.5, 0, 255).astype(np.uint8)
    found = follow_best(frames, measure_paths(frames, MAX_OBJECTS)[0])
    assert found is not None and not found.hidden.any()
    truth = np.stack([cx, np.full(n, cy)], axis=1) - 0.5
    err = np.linalg.norm(found.xy - truth, axis=1)
    assert float(np.sqrt(np.mean(err ** 2))) < 0.3
    # followed with the whole block's cut (50 x 36 px, its corners rounded by 2), not the crescent
    assert abs(found.area / (50 * 36 - (4 - np.pi) * 4) - 1) < 0.03


def _can(x, bar=None, seed=0, h=90, w=90):
    """A plain can (20 x 34 px, its centre at (x, 47) in render coordinates) hanging in front of a
    textured wall, in linear light through the camera model (blur, noise, sRGB, JPEG), gray uint8;
    bar: the x of a dark bar 22 px wide standing behind it."""
    import cv2

    from fitode.synth.scenes import _Sensor

    rng = np.random.default_rng(seed)
    wall = np.repeat((0.7 + 0.03 * R.value_noise(rng, h, w, (4, 12)))[..., None], 3, axis=2).astype(np.float32)
    cv = R.Canvas(wall, 4)
    if bar is not None:
        cv.paint(R.segment(bar, 0, bar, h, 11.0), np.float32([0.07] * 3), (bar - 13, 0, bar + 13, h))
    cv.paint(R.box(x, 47.0, 10, 17, 0.05, radius=1.0),
             lambda xx, yy: np.repeat((0.2 + 0.04 * np.cos((xx - x) / 7))[..., None], 3, axis=-1),
             (x - 20, 27, x + 20, 67))
    sensor = _Sensor(np.random.default_rng([seed, 1]), (h, w, 3), 1.0, 0.7, 85)
    return cv2.cvtColor(sensor(cv.image), cv2.COLOR_RGB2GRAY)


@pytest.mark.parametrize("side", [-8.0, 8.0])
def test_a_dark_bar_behind_one_edge_does_not_pull_the_place(side):
    # the bar covers the ring around one side of the can: the edge pixels there mix the can with
    # the bar, not with the wall the template holds, and misfit by only a share of that change;
    # trusted as much as the rest, they pulled the place 0.6 px towards the bar
    from fitode.video.follow import _cut, _refine

    template, weight, ref, _, _, centre = _cut(_can(45.0, seed=1), _can(-100.0, seed=3), 2.0, np.array([44.5, 46.5]))
    for sub in (0.0, 0.3):
        frame = _can(45.0 + sub, bar=45.0 + sub + side, seed=4).astype(np.float32)
        truth = centre + np.array([sub, 0.0])
        place = _refine(frame, template, weight, ref, truth)[0]
        assert np.linalg.norm(place - truth) < 0.25


def test_the_typical_cuts_are_never_none():
    from fitode.video.follow import _typical
    assert _typical([100.0, 200.0]).tolist() == [False, True]  # both off their median: the nearer one is kept
    assert _typical([100.0, 104.0, 300.0]).tolist() == [True, True, False]


def test_frames_given_as_an_array_are_tracked_as_a_videos_are():
    from fitode.video.track import track_array
    yy, xx = np.mgrid[:48, :64]
    centres = [(10.0 + 1.5 * t, 20.0 + 0.5 * t) for t in range(30)]
    frames = np.stack([np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / 8.0) for cx, cy in centres])[:, None]
    track = track_array(0.2 + 0.6 * frames)
    assert track is not None and len(track) == 30
    assert np.nanmax(np.abs(track.xy - np.array(centres))) < 0.3  # in the array's own pixels
    assert track_array(np.random.default_rng(0).random((30, 2, 1, 1))) is None  # columns, not pictures
    assert track_array(np.zeros((30, 1, 16, 16))) is None  # nothing to see


def test_a_large_object_is_searched_for_at_half_the_resolution_and_found_as_exactly(monkeypatch):
    """A ball 40 px across (a 1080p clip's), hidden for 6 frames by a bar: the search after it runs
    on halved frames (a sixteenth of the correlation's work) and the refinement from its peak
    places the ball as the full resolution's search did (0.119 px RMS both)."""
    import fitode.video.follow as follow

    factors = []
    full = follow._correlation

    def counted(*args):
        corr, f = full(*args)
        factors.append(f)
        return corr, f
    monkeypatch.setattr(follow, "_correlation", counted)
    n, h, w = 60, 240, 320
    rng = np.random.default_rng(0)
    wall = (0.6 + 0.05 * R.value_noise(rng, h, w, (4, 12))).astype(np.float32)
    t = np.arange(n) / 30.0
    cx, cy = w / 2 + 90 * np.cos(2.5 * t), h / 2 + 25 * np.sin(2.5 * t) ** 2
    frames = np.empty((n, h, w), np.uint8)
    for i in range(n):
        cv = R.Canvas(wall.copy(), 4)
        x, y = cx[i], cy[i]
        cv.paint(R.circle(x, y, 20.0), lambda xx, yy: 0.25 + 0.2 * (np.sin((xx - x) * 0.5) > 0), (x - 21, y - 21, x + 21, y + 21))
        if 24 <= i < 30:
            cv.paint(R.box(x, h / 2, 30, h / 2), 0.05, (x - 31, 0, x + 31, h))
        frames[i] = np.clip((cv.image + rng.normal(0, 0.01, cv.image.shape)) * 255 + 0.5, 0, 255).astype(np.uint8)
    found = follow_best(frames, measure_paths(frames, MAX_OBJECTS)[0])
    assert 2 in factors
    assert list(np.flatnonzero(found.hidden)) == list(range(24, 30))
    err = np.linalg.norm(found.xy[~found.hidden] - (np.stack([cx, cy], axis=1) - 0.5)[~found.hidden], axis=1)
    assert float(np.sqrt(np.mean(err ** 2))) < 0.2 and err.max() < 0.5


def _small_swing(n=90, h=130, w=120, amplitude=12.0, seed=3):
    """A ball 28 px across on a string from a pivot above the frame, swinging by less than its own
    size with its string (gray uint8 frames), and the ball's true centre per frame."""
    rng = np.random.default_rng(seed)
    wall = (0.62 + 0.03 * R.value_noise(rng, h, w, (4, 12))).astype(np.float32)
    pivot, length = (w / 2, -60.0), 160.0
    theta = (amplitude / length) * np.cos(2 * np.pi * np.arange(n) / 40.0)
    bx, by = pivot[0] + length * np.sin(theta), pivot[1] + length * np.cos(theta)
    frames = np.empty((n, h, w), np.uint8)
    for i in range(n):
        cv = R.Canvas(wall.copy(), 4)
        cv.paint(R.segment(pivot[0], pivot[1], bx[i], by[i], 2.0), 0.2, (0, 0, w, by[i]))
        x, y = bx[i], by[i]
        cv.paint(R.circle(x, y, 14.0), lambda xx, yy, x=x, y=y: 0.35 + 0.004 * (xx - x) - 0.004 * (yy - y),
                 (x - 15, y - 15, x + 15, y + 15))
        frames[i] = np.clip((cv.image + rng.normal(0, 0.005, cv.image.shape)) * 255 + 0.5, 0, 255).astype(np.uint8)
    return frames, np.stack([bx, by], axis=1) - 0.5


def test_a_swing_narrower_than_the_object_is_followed():
    # the ball swings 24 px across and the template (ball and string) is about 30 px across: its
    # range alone says it moves less than its size, as a hand that has let go does; its course says
    # it swings four times that far
    frames, truth = _small_swing()
    found = follow_best(frames, measure_paths(frames, MAX_OBJECTS)[0])
    assert found is not None and not found.hidden.any()
    assert np.ptp(found.xy[:, 0]) < np.sqrt(found.area)
    assert np.corrcoef(found.xy[:, 0], truth[:, 0])[0, 1] > 0.99


def test_travelled_counts_a_course_not_the_noise_of_a_place():
    from fitode.video.follow import travelled
    rng = np.random.default_rng(0)
    still = np.array([50.0, 40.0]) + rng.normal(0, 0.3, (200, 2))
    assert travelled(still) < 4.0  # a hand that has let go, its place read to 0.3 px
    moved = np.where(np.arange(200)[:, None] < 100, [50.0, 40.0], [80.0, 40.0]) + rng.normal(0, 0.3, (200, 2))
    assert 29.0 < travelled(moved) < 34.0  # it moved once: its range
    t = np.arange(200)
    swing = np.stack([50 + 10 * np.sin(2 * np.pi * t / 50), np.full(200, 40.0)], axis=1)
    assert travelled(swing) > 4 * 20 * 0.8  # four swings, each 40 px there and back
