"""Least-squares fits of the reduced model and of the reduced model augmented by one effect
(the state parameters, the onset delay τ and that effect's strength), from the reduced fit."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..mechanics.prototype import REALISTIC, UPPER
from .data import STATE, block_residual

MAX_NFEV = 12


@dataclass
class Fit:
    x: np.ndarray         # state parameters then τ [s]
    strength: float       # effect strength [-] (0 for the reduced model)
    effect: str | None


def _scale(x0):
    s = np.abs(np.asarray(x0, float))
    s[-1] = 1e-4  # τ [s]
    return np.maximum(s, 1e-6)


def _bounds(x0):
    lo = np.asarray(x0, float) * 0.2
    hi = np.asarray(x0, float) * 5.0
    lo[-1], hi[-1] = -2e-3, 5e-3
    return lo, hi


def fit_reduced(x0, data, breaker, operation, mask=None, max_nfev=MAX_NFEV) -> Fit:
    """Polish the reduced model on the blocks in ``mask`` (all when None)."""
    m = np.ones(data.t.size, bool) if mask is None else mask

    def fun(x):
        return block_residual(x, data, breaker, operation)[m]

    lo, hi = _bounds(x0)
    res = least_squares(fun, np.clip(x0, lo, hi), bounds=(lo, hi), x_scale=_scale(x0),
                        max_nfev=max_nfev, diff_step=1e-6)
    return Fit(res.x, 0.0, None)


def fit_augmented(base: Fit, data, breaker, operation, effect: str, mask=None,
                  strength: float | None = None, *, start: Fit | None = None,
                  max_nfev: int = MAX_NFEV, cold: bool = True) -> Fit:
    """Fit state parameters, τ and ``effect``'s strength (or hold ``strength`` fixed).

    ``start`` warm-starts the fit (the refinement of a screened candidate); ``cold`` adds a
    strong cold start to it (skipped when the screened fit already explains most of the gap,
    to bound the runtime). The result is never
    worse than ``base`` on the fitted blocks: when the optimiser stops early above the reduced
    model's cost, the reduced fit is returned with strength 0 (the effect explains nothing), so
    in-sample shrinks are not negative artefacts of an unconverged fit.
    """
    m = np.ones(data.t.size, bool) if mask is None else mask
    n = len(base.x)
    lo, hi = _bounds(base.x)
    base_cost = 0.5 * float(np.sum(block_residual(base.x, data, breaker, operation)[m] ** 2))
    if strength is not None:
        def fun(x):
            return block_residual(x, data, breaker, operation, effect, strength)[m]
        res = least_squares(fun, np.clip(base.x, lo, hi), bounds=(lo, hi), x_scale=_scale(base.x),
                            max_nfev=max_nfev, diff_step=1e-6)
        return Fit(res.x, float(strength), effect)

    s_lo = 0.02 * REALISTIC[effect] if effect == "rod_elasticity" else 0.0
    s_hi = UPPER[effect]

    def fun(z):
        return block_residual(z[:n], data, breaker, operation, effect, z[n])[m]

    if start is not None:
        # refinement: from the screened solution and from a strong cold start (the screened fit
        # can sit in a shallow local minimum near zero strength)
        starts = [(base.x, 1.5 * REALISTIC[effect])] if cold or start.strength <= 0 else []
        if start.strength > 0:
            starts.insert(0, (start.x, start.strength))
    else:  # cold start (also when the screened fit fell back to the reduced model)
        starts = [(base.x, 0.3 * REALISTIC[effect])]
        if effect == "rod_elasticity":  # the rod's ringing is multimodal in its frequency
            starts += [(base.x, 0.7 * REALISTIC[effect]), (base.x, 1.5 * REALISTIC[effect])]
    best = None
    for x0, s0 in starts:
        z0 = np.append(np.clip(x0, lo, hi), min(max(s0, s_lo), s_hi))
        res = least_squares(fun, z0, bounds=(np.append(lo, s_lo), np.append(hi, s_hi)),
                            x_scale=np.append(_scale(base.x), REALISTIC[effect]),
                            max_nfev=max_nfev, diff_step=1e-5)
        if best is None or res.cost < best.cost:
            best = res
    if best.cost >= base_cost:
        return Fit(np.array(base.x, float), 0.0, effect)
    return Fit(best.x[:n], float(best.x[n]), effect)


def state_dict(fit: Fit, operation: str) -> dict:
    return {k: float(v) for k, v in zip(STATE[operation], fit.x)}
