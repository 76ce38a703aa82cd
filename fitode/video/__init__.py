"""Reading a video (or a folder of images, or a .npy array) into small preprocessed frames.

    clip = read_video("pendulum.mp4", fps=120, start=2.0, roi=(100, 0, 400, 300))
    clip.frames      # float32 (T, C, H, W) in [0, 1]
    clip.dt          # seconds between kept frames: stride / fps

Order of operations, per frame, while decoding: trim (start/end) -> crop (roi) -> gray (or RGB)
-> multiply by the mask -> resize -> keep every stride-th frame. Only one full-resolution frame
is alive at a time; what accumulates is the small preprocessed frames (about 29 KB each at the
default 64-pixel short side, gray). With `stride="auto"` every frame of the trimmed range is
kept until the stride is chosen (see `fitode.stride`), then only every stride-th.

Times (`start`, `end`, `Clip.times`) are in the seconds of the frame rate in use: with
`fps=120` on a slow-motion clip that the container calls 30 fps, they are real seconds, not
playback seconds. Sizes are typed WxH on the command line (640x480) and are (H, W) in Python.

The modules, by job: `clip` (the Clip record, VideoError), `flags` (parsing and checking the
options, the argparse flags), `sources` (video file, folder of images, .npy array), `mask`,
`preprocess` (one frame: crop, gray, mask, resize) and `read` (the loop that ties them).
"""
from fitode.video.clip import Clip, VideoError
from fitode.video.flags import (add_video_arguments, parse_roi, parse_size, parse_stride,
                                video_kwargs)
from fitode.video.read import read_video
from fitode.video.sources import IMAGE_SUFFIXES, MAX_FPS

__all__ = ["Clip", "VideoError", "read_video", "parse_roi", "parse_size", "parse_stride",
           "add_video_arguments", "video_kwargs", "IMAGE_SUFFIXES", "MAX_FPS"]
