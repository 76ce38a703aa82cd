"""The source frames the read keeps for pictures (fitode.video.stills): spread over the clip,
at full resolution, bounded in number whatever the clip's length, the same as a second decode."""
from __future__ import annotations

import numpy as np

from fitode.video import read_video
from fitode.video.stills import KEPT, StillKeeper, kept_stills, source_stills


def test_the_read_keeps_full_resolution_frames_a_second_decode_would_give(tmp_path):
    # a gray ramp that brightens frame by frame, 200 frames of 120x90: the fit's frames are shrunk, the stills not
    arr = np.stack([np.tile(np.linspace(0, 200, 120, dtype=np.float32), (90, 1)) + i * 0.25
                    for i in range(200)]).astype(np.uint8)
    np.save(tmp_path / "ramp.npy", arr)
    clip = read_video(tmp_path / "ramp.npy", fps=50, stride=1)
    kept = sorted(clip.stills)
    assert KEPT // 2 <= len(kept) <= 2 * KEPT and kept[0] == 0 and kept[-1] >= 150  # spread over the clip
    got = kept_stills(clip.stills, kept[:3])
    again = source_stills(tmp_path / "ramp.npy", kept[:3])
    for i in kept[:3]:
        assert got[i].shape == (90, 120, 3)  # source resolution, RGB
        assert np.abs(got[i] - again[i]).max() <= 0.5 / 255 + 1e-6  # kept as 8 bits: the same picture


def test_a_clip_longer_than_expected_keeps_no_more_frames():
    keeper = StillKeeper("RGB", expected=10, keep=4)
    for i in range(1000):
        keeper.add(i, np.full((4, 6, 3), i % 255, np.uint8), (1 / 255, 0.0))
    assert len(keeper.frames) <= 8 and min(keeper.frames) == 0 and max(keeper.frames) > 500
