"""Any equation, simulated with the project's RK4 and drawn the paper's three ways."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from fitode.errors import FitodeError
from fitode.synth.paper import _check_common, mapping_text, render_signal
from fitode.synth.trajectory import simulate_system
from fitode.synth.video import SynthVideo


def resolve_system(system_or_text):
    """(OdeSystem, shipped name or None) from a shipped system name, equation text or an OdeSystem."""
    from fitode.eqfile import load_system
    from fitode.eqparse import OdeSystem, parse

    if isinstance(system_or_text, OdeSystem):
        return system_or_text, None
    text = str(system_or_text).strip()
    if "=" in text:
        return parse(text), None
    return load_system(text).parse(), text


def render_equation(system_name_or_text, *, constants: Mapping[str, float],
                    y0: Mapping[str, float], n_frames: int = 270, dt: float = 0.2,
                    mode: str = "motion", size: int = 50, seed: int = 0, substeps: int = 20,
                    noise: float = 0.0, max_angle: float = 120.0,
                    mapping: Mapping[str, tuple[float, float]] | None = None, ss: int = 4) -> SynthVideo:
    """Simulate an equation (shipped system name, text or OdeSystem) and render it.

    constants: a value for every learnable constant (and optionally known ones, such as g,
        to change them). y0: a value for every state and optionally its derivatives below
        its order ({"theta": 0.5, "theta'": 0}; missing derivatives are 0).
    The trajectory is integrated with fitode.codegen's RK4 at `substeps` steps per frame.
    Each state variable z is drawn as u = (z - offset) / scale in one panel of size x size
    (panels side by side for several states), with the paper's renderings (see
    fitode.synth.paper): mode "motion" (pendulum angle = max_angle * u degrees), "intensity"
    (gray 0.6 + 0.4 u) or "scale" (half radii 0.2 size (1 +- u)). mapping gives
    {state: (offset, scale)}; by default each state's range over the video maps to [-1, 1].
    """
    _check_common(mode, n_frames, dt, size, ss)
    if int(substeps) < 1:
        raise FitodeError(f"substeps must be at least 1, got {substeps}")
    ode, shipped = resolve_system(system_name_or_text)
    known = {k: float(v) for k, v in constants.items()}
    latent, names, full, labels = simulate_system(ode, known, dict(y0), int(n_frames), float(dt),
                                                  substeps=int(substeps))
    maps = {}
    panels = []
    for j, name in enumerate(names):
        z = latent[:, j]
        if mapping is not None and name in mapping:
            off, sc = (float(v) for v in mapping[name])
        else:
            lo, hi = float(z.min()), float(z.max())
            off, sc = (hi + lo) / 2, (hi - lo) / 2
        if not (np.isfinite(sc) and abs(sc) > 1e-12 * max(1.0, abs(off))):
            sc = 1.0  # a constant state: draw it at its offset
        maps[name] = (off, sc)
        panels.append(render_signal((z - off) / sc, mode, size=size, seed=seed + j, max_angle=max_angle,
                                    ss=ss, noise=noise))
    frames = np.concatenate(panels, axis=2) if len(panels) > 1 else panels[0]
    truth = {n: known[n] for n in ode.learnable if n in known}
    fixed = {n: float(known.get(n, v)) for n, v in ode.fixed.items()}
    meta = {
        "generator": "equation", "kind": mode, "system": shipped, "seed": seed, "size": size,
        "n_frames": n_frames, "dt": dt, "substeps": int(substeps), "integrator": "rk4",
        "y0": {k: float(v) for k, v in y0.items()}, "fixed": fixed, "noise": noise, "supersampling": ss,
        "mapping": {n: {"offset": o, "scale": s} for n, (o, s) in maps.items()},
        "drawing": mapping_text(mode, max_angle) + ", u = (state - offset) / scale"
                   + ("; one panel per state, left to right" if len(names) > 1 else ""),
    }
    equation = ode.text or "; ".join(ode.normal_form())
    return SynthVideo(frames=frames, dt=float(dt), truth=truth, latent=latent, equation=equation,
                      latent_names=tuple(names), state=full, state_names=tuple(labels), meta=meta)
