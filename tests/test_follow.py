"""The object tracker (fitode.video.follow): where the object is, and where it is hidden."""
import numpy as np

from fitode.synth import render as R
from fitode.video.follow import follow_best
from fitode.video.track import MAX_OBJECTS, measure_paths


def _clip(n=60, h=120, w=160, cover=None, seed=0):
    """A striped ball swinging across a textured wall (gray uint8 frames) and its true centre per
    frame (pixel (0, 0)'s centre at (0, 0)); cover: frames in which a dark bar stands over it."""
    rng = np.random.default_rng(seed)
    wall = (0.6 + 0.05 * R.value_noise(rng, h, w, (4, 12))).astype(np.float32)
    t = np.arange(n) / 30.0
    cx = w / 2 + 40 * np.cos(2.5 * t)
    cy = h / 2 + 10 * np.sin(2.5 * t) ** 2
    frames = np.empty((n, h, w), np.uint8)
    for i in range(n):
        cv = R.Canvas(wall.copy(), 4)
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
