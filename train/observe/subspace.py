"""The signal subspace: what a free encoder reads of the frames.

An encoder with more free weights than frames can draw any curve out of pixel noise (a linear
encoder on 64x85 frames of a dimming lamp gave a decay rate of the wrong sign). The frames are
projected on their leading principal components first. Where the singular values drop by a
clear gap (one ratio of neighbours above SUBSPACE_JUMP: a lamp that dims is one component, then
video noise), the components above the gap are kept. Otherwise (a moving object spreads over
many components with no gap) those above the noise floor: SUBSPACE_GAP times the median singular
value of the second quarter of the spectrum, where only noise and the tail of the motion live;
at most SUBSPACE_CAP. An mlp or linear encoder then reads the k coefficients, which is the same
function class as reading the projected frames (its first layer absorbs the projection) at a
fraction of the cost; a cnn reads the projected frames.
"""
from __future__ import annotations

import numpy as np
import torch

from ..encoders import normalise_frames

SUBSPACE_GAP = 3.0
SUBSPACE_JUMP = 3.0
SUBSPACE_CAP = 32
SCORE_COMPONENTS = 8


def signal_subspace(frames: torch.Tensor, architecture: str = "mlp", fit_frames: int | None = None,
                    keep: bool = True) -> tuple[torch.Tensor, np.ndarray, int, str]:
    """Raw float frames (T, C, H, W) -> (what the encoder reads, the frames' leading
    SCORE_COMPONENTS principal-component coefficients (T, SCORE_COMPONENTS), the rank kept, one
    line on why). The components come from the first fit_frames frames (the training range) only.
    keep=False: the encoder reads every normalised pixel (no subspace)."""
    x = normalise_frames(frames)
    n_fit = x.shape[0] if fit_frames is None else int(fit_frames)
    flat = x.reshape(x.shape[0], -1).double()
    mean = flat[:n_fit].mean(dim=0, keepdim=True)
    centred = flat - mean
    fit = centred[:n_fit]
    evals, evecs = torch.linalg.eigh(fit @ fit.T)  # the T x T Gram matrix is small where pixels are many
    order = torch.argsort(evals, descending=True)
    sv = evals[order].clamp_min(0).sqrt()
    k_max = int((sv > 1e-9 * sv[0]).sum()) if sv[0] > 0 else 0
    floor = float(sv[len(sv) // 4: max(len(sv) // 2, len(sv) // 4 + 1)].median()) if len(sv) >= 8 else 0.0
    above = int((sv > SUBSPACE_GAP * floor).sum()) if floor > 0 else k_max
    head = sv[: min(SUBSPACE_CAP, k_max) + 1]
    jumps = (head[:-1] / head[1:].clamp_min(1e-300)) if len(head) > 1 else head[:0]
    jump = int(torch.argmax(jumps)) if len(jumps) else -1
    gapped = jump >= 0 and float(jumps[jump]) > SUBSPACE_JUMP
    rank = (jump + 1) if gapped else max(1, min(above, SUBSPACE_CAP, k_max)) if k_max else 1
    # pixel directions of the leading components: V = X^T U / s
    lead = order[: max(rank, SCORE_COMPONENTS)]
    u = evecs[:, lead]
    s = sv[: lead.numel()].clamp_min(1e-12)
    basis = (fit.T @ u) / s  # (pixels, K), orthonormal columns
    coefs = centred @ basis  # (T, K): every frame, the held-out ones too
    components = coefs[:, :SCORE_COMPONENTS].cpu().numpy()
    if not keep:
        return x, components, k_max, "the encoder reads every pixel (no signal subspace)"
    plural = "s" if rank != 1 else ""
    if gapped:
        note = (f"signal subspace: {rank} principal component{plural} of the frames (the singular values "
                f"drop {_times(float(jumps[jump]))} after the {rank}{_th(rank)})")
    else:
        ratio = f"{float(sv[rank - 1] / floor):.1f}x" if floor > 0 else "n/a"
        note = (f"signal subspace: {rank} principal component{plural} of the frames "
                + (f"(capped at {SUBSPACE_CAP}; " if above > SUBSPACE_CAP else "(")
                + f"the last kept stands {ratio} above the noise floor)")
    head = coefs[:, :rank]
    if architecture == "cnn":
        inputs = (head @ basis[:, :rank].T + mean).reshape(x.shape).to(x.dtype)
    else:
        inputs = (head / s[0] * np.sqrt(n_fit)).to(x.dtype).reshape(x.shape[0], rank, 1, 1)
    return inputs, components, rank, note


def _times(ratio: float) -> str:
    return "over 1000x" if ratio > 1000 else f"{ratio:.0f}x"


def _th(k: int) -> str:
    return {1: "st", 2: "nd", 3: "rd"}.get(k if k < 20 else k % 10, "th")
