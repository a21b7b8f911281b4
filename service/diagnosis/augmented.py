"""Least-squares fits of the reduced model and of the reduced model augmented by one effect
(the state parameters, the onset delay τ and that effect's strength), from the reduced fit."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..prototypes.a import REALISTIC, SHAPES, SIGNED, shape_bounds, shape_defaults
from ..prototypes.a.effects import FIT_UPPER
from .data import STATE, block_residual

MAX_NFEV = 12


@dataclass
class Fit:
    x: np.ndarray         # state parameters then τ [s]
    strength: float       # effect strength [-] (0 for the reduced model)
    effect: str | None
    shape: np.ndarray | None = None   # the effect family's shape parameters (SHAPES order)


# Deterministic extra starts of each family's shape (besides the prototype's defaults): forms far
# from the default that a local fit from the default would not reach (signs, exponents, sides).
ALT_SHAPES = {
    "linkage_kinematics": [(0.4, 0.0), (-0.4, 0.0), (0.0, 0.8)],
    "orifice_buffer": [(1.4, 0.25, 0.01)],
    "puffer_gas": [(1.2, 2.2, 40.0)],
    "rod_elasticity": [(0.08, 1.0)],
    "stribeck_friction": [(1.0, 1.2)],
    "viscous_friction": [(0.6,), (-0.6,)],
    "spring_nonlinearity": [(3.0, 0.0), (2.0, 1.0)],
    "sensor_nonlinearity": [(2.0, 0.0), (3.0, 0.0)],
    "cam_friction": [(0.7,), (-0.7,)],
    "contact_wipe": [(0.85, 0.2), (0.6, 0.8)],
}


def _scale(x0):
    s = np.abs(np.asarray(x0, float))
    s[-1] = 1e-4  # τ [s]
    return np.maximum(s, 1e-6)


def _bounds(x0):
    lo = np.asarray(x0, float) * 0.2
    hi = np.asarray(x0, float) * 5.0
    lo[-1], hi[-1] = -2e-3, 5e-3
    return lo, hi


def strength_bounds(effect: str):
    """Bounds of an effect's fitted strength: [0, UPPER], or ±UPPER for the signed families."""
    if effect == "rod_elasticity":  # ε = (150 Hz / f)²: 50–500 Hz
        return 0.09, 9.0
    return (-FIT_UPPER[effect] if effect in SIGNED else 0.0), FIT_UPPER[effect]


def n_shapes(effect: str) -> int:
    return len(SHAPES[effect])


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
                  max_nfev: int = MAX_NFEV, cold: bool = True, shape=None,
                  free_shape: bool = True) -> Fit:
    """Fit state parameters, τ, ``effect``'s strength and its family's shape parameters.

    ``strength`` (with ``shape``) held fixed fits the state and τ only (the hold-out on other
    captures). ``start`` warm-starts the fit (the refinement of a screened candidate); ``cold``
    adds the family's deterministic starts to it. Without ``start`` every deterministic start
    (the prototype's shape and ALT_SHAPES, both signs for the signed families) is screened. The
    result is never worse than ``base`` on the fitted blocks: when the optimiser stops above the
    reduced model's cost, the reduced fit is returned with strength 0.
    """
    m = np.ones(data.t.size, bool) if mask is None else mask
    n = len(base.x)
    lo, hi = _bounds(base.x)
    base_cost = 0.5 * float(np.sum(block_residual(base.x, data, breaker, operation)[m] ** 2))
    if strength is not None:
        def fun_fixed(x):
            return block_residual(x, data, breaker, operation, effect, strength, shape)[m]
        res = least_squares(fun_fixed, np.clip(base.x, lo, hi), bounds=(lo, hi), x_scale=_scale(base.x),
                            max_nfev=max_nfev, diff_step=1e-6)
        return Fit(res.x, float(strength), effect, None if shape is None else np.asarray(shape, float))

    s_lo, s_hi = strength_bounds(effect)
    sh_lo, sh_hi = shape_bounds(effect)
    sh0 = shape_defaults(effect)
    k = sh0.size if free_shape else 0

    def unpack(z):
        return z[:n], z[n], (z[n + 1:] if k else sh0)

    def fun(z):
        x, s, sh = unpack(z)
        return block_residual(x, data, breaker, operation, effect, s, sh)[m]

    real = REALISTIC[effect]
    signs = (1.0, -1.0) if effect in SIGNED else (1.0,)
    shapes = [sh0] + ([np.array(a, float) for a in ALT_SHAPES.get(effect, ())] if k else [])
    cold_starts = [(base.x, sg * 0.5 * real, sh) for sh in shapes for sg in signs]
    if effect == "rod_elasticity":  # the rod's ringing is multimodal in its frequency (ε = (150 Hz/f)²)
        cold_starts += [(base.x, eps, sh0) for eps in (0.15, 0.3, 1.0, 2.2)]
    if start is not None:
        starts = [(start.x, start.strength, start.shape if start.shape is not None else sh0)] \
            if start.strength != 0 else []
        if cold or not starts:
            starts += cold_starts
    else:
        starts = cold_starts
    z_lo = np.concatenate([lo, [s_lo], sh_lo if k else []])
    z_hi = np.concatenate([hi, [s_hi], sh_hi if k else []])
    z_scale = np.concatenate([_scale(base.x), [real], (sh_hi - sh_lo) * 0.25 if k else []])
    best = None
    for x0, s0, shs in starts:
        z0 = np.concatenate([np.clip(x0, lo, hi), [s0], np.asarray(shs, float) if k else []])
        z0 = np.clip(z0, z_lo, z_hi)
        res = least_squares(fun, z0, bounds=(z_lo, z_hi), x_scale=z_scale, max_nfev=max_nfev,
                            diff_step=1e-5)
        if best is None or res.cost < best.cost - 1e-9 * abs(best.cost):
            best = res
    if best.cost >= base_cost:
        return Fit(np.array(base.x, float), 0.0, effect, sh0)
    x, s, sh = unpack(best.x)
    return Fit(np.array(x), float(s), effect, np.array(sh, float))


def state_dict(fit: Fit, operation: str) -> dict:
    return {k: float(v) for k, v in zip(STATE[operation], fit.x)}
