"""Whether an effect is distinguishable from a change of the state parameters, at a capture's
noise level, and the bias it causes when it is not.

The effect's signature (prototype with the effect at its realistic strength, at the fitted
state) is refitted by the reduced model alone, noise-free. The parameter change δ is the bias
the effect causes when absorbed; the remainder r is what a fit can see. The effect is distinguishable when r stands out of
the noise: Σ count·r²/σ² ≥ 100 (a ΔBIC far beyond any threshold) and RMS(r) ≥ 0.3·σ.
"""

from __future__ import annotations

import numpy as np

from ..mechanics.prototype import REALISTIC
from .data import STATE, model_curve

MIN_CHI2 = 100.0
MIN_RMS_NOISE = 0.3


def jacobian(x, data, breaker, operation):
    """d model / d x at the block centres, by central differences; columns per entry of x."""
    base, _ = model_curve(x, data, breaker, operation, None)
    cols = []
    for i, xi in enumerate(x):
        h = 1e-5 if i == len(x) - 1 else 1e-4 * abs(xi)
        xp = np.array(x, float)
        xp[i] += h
        mp, _ = model_curve(xp, data, breaker, operation, None)
        cols.append((mp - base) / h)
    return base, np.column_stack(cols)


def absorption(effect, x, data, breaker, operation, base=None, J=None):
    """Projection of ``effect`` at its realistic strength on the parameter directions.

    Returns dict(effect, distinguishable, residual_rad, signature_rad, parameter_shift{name: %}).
    """
    if base is None or J is None:
        base, J = jacobian(x, data, breaker, operation)
    from dataclasses import replace

    from .augmented import fit_reduced

    m, _ = model_curve(x, data, breaker, operation, effect, REALISTIC[effect])
    w = np.sqrt(data.count) / data.noise
    d = m - base
    refit = fit_reduced(np.asarray(x, float), replace(data, y=m), breaker, operation, max_nfev=8)
    delta = refit.x - np.asarray(x, float)
    r = m - model_curve(refit.x, data, breaker, operation, None)[0]
    chi2 = float(np.sum((r * w) ** 2))
    rms = float(np.sqrt(np.mean(r * r)))
    names = STATE[operation]
    shift = {k: float(100.0 * delta[i] / x[i]) for i, k in enumerate(names)}
    shift["onset_delay_us"] = float(delta[len(names)] * 1e6)
    return {"effect": effect, "strength": REALISTIC[effect],
            "distinguishable": bool(chi2 >= MIN_CHI2 and rms >= MIN_RMS_NOISE * data.noise),
            "residual_rad": rms, "signature_rad": float(np.sqrt(np.mean(d * d))),
            "parameter_shift": shift}
