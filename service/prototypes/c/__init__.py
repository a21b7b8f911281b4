"""Prototype C: a third virtual prototype of the spring-operated breaker, written blind.

Its own equations of motion (Lagrange, cam as a constraint; an elastic pull rod, a gas puffer, ...)
reduce to the paper's reduced models when every effect is at strength 0. See docs/prototype-c.md.
"""

from __future__ import annotations

import numpy as np

from .capture import draw_conditions, simulate_capture
from .dataset import write_groups
from .effects import EFFECTS, OPERATIONS, OUTSIDE, REALISTIC, check_effects, draw_shapes
from .mechanism import Unit, draw_constants

__all__ = ["EFFECTS", "OUTSIDE", "OPERATIONS", "REALISTIC", "Unit", "make_unit", "draw_conditions",
           "simulate_capture", "write_groups"]


def make_unit(rng: np.random.Generator, *, effects=None, tolerance: float = 0.03) -> Unit:
    """One physical breaker: constants within ±tolerance of the design, effects {name: strength}.

    Each effect's shape parameters are drawn here, once; they stay fixed for the unit.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError("rng must be a numpy Generator (np.random.default_rng(seed))")
    eff = check_effects(effects)
    constants = draw_constants(rng, tolerance)
    shapes = draw_shapes(rng, eff)
    return Unit(constants=constants, effects=eff, shapes=shapes)
