"""Synthetic videos with known physics.

    from fitode import synth
    v = synth.paper_video("motion")                      # the paper's datasets (exact)
    v = synth.render_equation("pendulum", constants={...}, y0={...}, mode="motion")
    v = synth.scene("pendulum", 0.9, seed=3)             # realistic, 60 fps, 480x270
    synth.write_video(v, "clip.mp4")                     # + clip.truth.json

Every generator returns a SynthVideo: frames, dt, truth (the constants), latent (the true
state), equation, meta. fitode.synth.paper, .equation and .scenes document what is drawn.
"""
from fitode.synth.equation import render_equation, resolve_system
from fitode.synth.io import read_truth, truth_path, write_video
from fitode.synth.paper import MODES, PAPER_KINDS, paper_video
from fitode.synth.scenes import SCENES, SceneInfo, apparent_radius, scene
from fitode.synth.video import SynthVideo

__all__ = ["MODES", "PAPER_KINDS", "SCENES", "SceneInfo", "SynthVideo", "apparent_radius", "paper_video",
           "read_truth", "render_equation", "resolve_system", "scene", "truth_path", "write_video"]
