"""Shared, cached noise-free simulations for prototype C's tests."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from service.prototypes.c import make_unit, simulate_capture

FS = 128000.0


@lru_cache(maxsize=None)
def run(op: str, effect: str | None = None, strength: float = 1.0, seed: int = 1, tolerance: float = 0.0,
        cond: tuple = ()):
    """(travel, truth, unit) of a noise-free capture; the same seed gives the same constants."""
    effects = {effect: strength} if effect else None
    unit = make_unit(np.random.default_rng(seed), effects=effects, tolerance=tolerance)
    cap, truth = simulate_capture(unit, op, conditions=dict(cond) or None, rng=np.random.default_rng(0),
                                  noise_rad=0.0)
    return cap.travel, truth, unit


def delta(op: str, effect: str, seed: int = 1, strength: float = 1.0):
    """(travel with the effect - travel without [rad], truth without, truth with, unit with)."""
    t0, tr0, _ = run(op, None, seed=seed)
    t1, tr1, unit = run(op, effect, strength, seed=seed)
    n = min(t0.size, t1.size)
    return t1[:n] - t0[:n], tr0, tr1, unit


def index(t_s: float) -> int:
    return int(round(t_s * FS))
