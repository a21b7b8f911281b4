"""Whether an effect is distinguishable from a change of the state parameters, at a capture's
noise level, and the bias it causes when it is not.

The effect's signature (prototype with the effect at its realistic strength, at the fitted
state) is refitted by the reduced model alone, noise-free. The parameter change δ is the bias
the effect causes when absorbed; the remainder r is what a fit can see. The effect is
distinguishable when r stands out of the noise: Σ count·r²/σ² ≥ 100 (a ΔBIC far beyond any
threshold) and RMS(r) ≥ 0.3·σ.

The refit starts from the linearised projection δ₀ = J⁺·(signature) (Gauss–Newton step on the
state Jacobian), then polishes with a few nonlinear evaluations; the smaller remainder of the
two is kept. Starting from the projection makes exact absorptions (cam friction = BC/η) reach
the noise floor instead of being declared distinguishable by an unconverged refit.

The remainder's share per phase (``phase_share``) is where the effect's visible part lies: the
verdict requires the capture's worst phase to carry a fair share of the named effect's
remainder (see ``decide``).
"""

from __future__ import annotations

import numpy as np

from ..prototypes.a import REALISTIC
from .data import STATE, model_curve

MIN_CHI2 = 100.0
MIN_RMS_NOISE = 0.3


def _cam_friction_state(x, strength, operation):
    """cam_friction is exactly BC -> BC/η with η = 1 − strength (see prototype/cam_friction.py)."""
    y = np.array(x, float)
    y[STATE[operation].index("BC")] /= 1.0 - strength
    return y


# Effects that are an exact re-parametrisation of the state: the mapped state is tried as a start,
# so the check cannot miss the absorption by landing in a wrong basin.
EXACT_EQUIVALENCE = {"cam_friction": _cam_friction_state}
REFIT_NFEV = 8


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


def _phase_share(r, data, bounds, tau):
    """Share of Σ count·r² per phase ({name: fraction}), phases in model time."""
    if bounds is None:
        return {}
    tm = data.t - tau
    e = data.count * r * r
    tot = float(e.sum()) or 1.0
    out = {}
    for i, (name, a, b) in enumerate(bounds):
        last = i == len(bounds) - 1
        sel = (tm >= a) & ((tm <= b + 1e-9) if last else (tm < b))
        out[name] = float(e[sel].sum()) / tot
    return out


def absorption(effect, x, data, breaker, operation, base=None, J=None, bounds=None):
    """Projection of ``effect`` at its realistic strength on the parameter directions.

    Returns dict(effect, distinguishable, residual_rad, signature_rad, parameter_shift{name: %},
    phase_share{phase: fraction of the remainder's χ²} when ``bounds`` are given).
    """
    if base is None or J is None:
        base, J = jacobian(x, data, breaker, operation)
    from dataclasses import replace

    from .augmented import fit_reduced

    x = np.asarray(x, float)
    m, _ = model_curve(x, data, breaker, operation, effect, REALISTIC[effect])
    w = np.sqrt(data.count) / data.noise
    d = m - base
    # linearised projection (weighted), then a short nonlinear polish from it
    scale = np.maximum(np.abs(x), 1e-6)
    scale[-1] = 1e-4
    Jw = J * scale * w[:, None]
    step, *_ = np.linalg.lstsq(Jw, d * w, rcond=None)
    x_lin = x + step * scale
    lo, hi = x * 0.2, x * 5.0
    lo[-1], hi[-1] = -2e-3, 5e-3
    # the projection is trusted only as a local step (|Δ| < 30 %, |Δτ| < 1 ms): the closing's
    # Jacobian is ill-conditioned and a long linear step lands in a wrong basin
    sane = bool(np.all(np.abs(step[:-1]) < 0.3) and abs(step[-1] * scale[-1]) < 1e-3
                and np.all(x_lin > lo) and np.all(x_lin < hi))
    best = None
    starts = [x, x_lin] if sane else [x]
    if effect in EXACT_EQUIVALENCE:
        starts.append(EXACT_EQUIVALENCE[effect](x, REALISTIC[effect], operation))
    for xc in starts:
        r = m - model_curve(xc, data, breaker, operation, None)[0]
        c2 = float(np.sum((r * w) ** 2))
        if best is None or c2 < best[0]:
            best = (c2, xc, r)
    for xc in starts:  # polish from each start while the remainder is not clearly absorbed
        if best[0] < 0.5 * MIN_CHI2:
            break
        refit = fit_reduced(xc, replace(data, y=m), breaker, operation, max_nfev=REFIT_NFEV)
        r = m - model_curve(refit.x, data, breaker, operation, None)[0]
        c2 = float(np.sum((r * w) ** 2))
        if c2 < best[0]:
            best = (c2, refit.x, r)
    chi2, xr, r = best
    delta = xr - x
    rms = float(np.sqrt(np.mean(r * r)))
    names = STATE[operation]
    shift = {k: float(100.0 * delta[i] / x[i]) for i, k in enumerate(names)}
    shift["onset_delay_us"] = float(delta[len(names)] * 1e6)
    return {"effect": effect, "strength": REALISTIC[effect],
            "distinguishable": bool(chi2 >= MIN_CHI2 and rms >= MIN_RMS_NOISE * data.noise),
            "residual_rad": rms, "signature_rad": float(np.sqrt(np.mean(d * d))),
            "parameter_shift": shift, "chi2": chi2,
            "phase_share": _phase_share(r, data, bounds, x[-1])}
