"""Lines that describe an equation to its user, shared by `fitode check` and a run's header.

Here, not in either, so the report does not import a command's module.
"""
from __future__ import annotations


def gauge_lines(system, observation=None) -> list[str]:
    """How the equation's state relates to the latent (fitode.eqparse.gauge): what a fit learns,
    as the observation model reads it where one is given (a state measured in its own units has
    no gauge)."""
    from fitode.eqparse.gauge import gauge_plan
    try:
        plan = gauge_plan(system)
        if observation is not None:
            plan = observation.gauge_plan(plan)
    except Exception:  # noqa: BLE001 - advice only: the symmetry test can fail on unusual equations
        return ["gauge: could not be analysed; the state is taken as the latent"]
    return ["gauge (the equation's state from the latent z):"] + [f"  {g.describe()}" for g in plan.values()]


def hint_lines(system) -> list[str]:
    """The parser's advice that stops nothing (a constant where a state is expected), one line each."""
    return [f"hint: {h}" for h in system.hints]
