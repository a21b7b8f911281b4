"""An unknown design's structure, estimated from the opening curve itself: the buffer
engagement angle α0 and the puffer damping CO (``[unknown_design] estimate = ["alpha0", "CO"]``).

α0 is first located by a profile: the fitted parameters are carried by least squares along a
grid of α0 values (each step starting from the previous one's answer), and the α0 of least
residual is kept. A joint least-squares step then frees α0 (and CO) with the model parameters, and
the covariance of the joint fit gives every CI, so the uncertainty they add is in the CIs.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..mechanics.breaker import Breaker
from ..mechanics.characteristics import travel_characteristics
from .curves import OpeningCurves
from .polish import batched_jacobian, polish
from .uncertainty import Z95, correlated_covariance
from .window import FitWindow, block_samples, decimate

# α0 profile grid, as fractions of the stroke: buffers engage in the last half of the opening
# stroke (the paper's reference: 0.70); 0.30–0.98 leaves room on both sides.
ALPHA0_GRID = np.linspace(0.30, 0.98, 35)
# CO (puffer damping, caec·raec²/J2) when the design is unknown: searched in 0–2000 s⁻¹ (the
# reference breaker's is 92.6 s⁻¹; 2000 s⁻¹ would stop an opening in ~1 ms).
CO_BOUNDS = (0.0, 2000.0)
MODEL = ("AO", "BO", "DO", "EO")


def _with(breaker: Breaker, alpha0: float, co: float) -> Breaker:
    """``breaker`` with α0 [rad] and CO [s⁻¹] (CO set through caec, the rest kept)."""
    return dataclasses.replace(breaker, alpha0=float(alpha0), caec=float(co) * breaker.J2 / breaker.raec**2)


def _rows_factory(window: FitWindow, breaker: Breaker, settings):
    """Weighted residual rows for X columns AO, BO, DO, EO, α0, CO, τ (one model per row)."""
    grid = decimate(window.t, window.y, block_samples(settings.block_open, window.sample_rate))
    w = grid.weight

    def rows(X):
        X = np.atleast_2d(X)
        out = np.empty((X.shape[0], grid.t.size))
        for i, x in enumerate(X):
            curves = OpeningCurves(_with(breaker, x[4], x[5]), grid)
            out[i] = w * (curves.full(np.array([[x[0], x[1], x[2], x[3], x[6]]]))[0] - grid.y)
        return out

    return rows


def fit_structure(result, window: FitWindow, breaker: Breaker, settings) -> Breaker:
    """Estimate an unknown design's structure (``breaker.estimate_structure``: α0, and CO when
    listed) for an opening ``result`` fitted with the breaker file's values; update ``result``
    (parameters, CIs from the joint covariance, ``structure``) and return the breaker with the
    estimates."""
    free = [n for n in ("alpha0", "CO") if n in breaker.estimate_structure]
    rows = _rows_factory(window, breaker, settings)
    p = result.parameters
    stroke = breaker.stroke
    x = np.array([p["AO"], p["BO"], p["DO"], p["EO"], breaker.alpha0, breaker.CO, result.onset_delay_s])
    lo_tau, hi_tau = window.tau_range or (0.0, settings.tau_max)
    lower = np.array([1.0, 1.0, 0.0, 0.0, ALPHA0_GRID[0] * stroke, CO_BOUNDS[0], lo_tau])
    upper = np.array([1e6, 1e6, 1e4, 1e6, ALPHA0_GRID[-1] * stroke, CO_BOUNDS[1], hi_tau])
    scale = np.array([3000.0, 5000.0, 30.0, 5000.0, 0.05 * stroke, 50.0, 1e-3])
    evaluations = 0
    if "alpha0" in free:
        # Profile over α0 from the file's value outwards (continuation keeps each start in its
        # basin), the model parameters and τ carried along by least squares.
        keep = [0, 1, 2, 3, 6]

        def at_alpha(a, x0):
            def fixed(X):
                X = np.atleast_2d(X)
                full = np.column_stack([X[:, :4], np.full(len(X), a), np.full(len(X), x0[5]), X[:, 4]])
                return rows(full)
            pol = polish(fixed, x0[keep], lower[keep], upper[keep], scale[keep], max_nfev=20)
            xf = x0.copy()
            xf[keep], xf[4] = pol.x, a
            return xf, float(np.sum(rows(xf[None, :]) ** 2)), pol.evaluations

        grid = ALPHA0_GRID * stroke
        start = int(np.argmin(np.abs(grid - breaker.alpha0)))
        sse = np.full(grid.size, np.inf)
        sols = [None] * grid.size
        for order in (range(start, grid.size), range(start - 1, -1, -1)):
            xc = x.copy()
            for k in order:
                xc, sse[k], n = at_alpha(grid[k], xc)
                sols[k] = xc
                evaluations += n
        x = sols[int(np.argmin(sse))]
    # The joint step: every free structure value with the model parameters and τ.
    idx = [0, 1, 2, 3] + [{"alpha0": 4, "CO": 5}[n] for n in free] + [6]

    def joint(X):
        X = np.atleast_2d(X)
        full = np.repeat(x[None, :], len(X), axis=0)
        full[:, idx] = X
        return rows(full)

    pol = polish(joint, x[idx], lower[idx], upper[idx], scale[idx], max_nfev=60)
    evaluations += pol.evaluations
    if float(np.sum(joint(pol.x[None, :]) ** 2)) <= float(np.sum(joint(x[idx][None, :]) ** 2)):
        x = x.copy()
        x[idx] = pol.x
    resid, jac = batched_jacobian(joint, x[idx], scale[idx], lower[idx], upper[idx])
    unc = correlated_covariance(jac, resid, window.noise_rad, scale[idx], n_model=len(idx) - 1)
    names = list(MODEL) + free + ["tau"]
    for i, n in enumerate(MODEL):
        result.parameters[n] = float(x[i])
        result.stderr[n] = float(unc.stderr[i])
        result.ci95[n] = (float(x[i] - Z95 * unc.stderr[i]), float(x[i] + Z95 * unc.stderr[i]))
    result.onset_delay_s = float(x[6])
    keep_c = [0, 1, 2, 3, len(idx) - 1]
    result.correlation = unc.correlation[np.ix_(keep_c, keep_c)].tolist()
    result.identifiable = result.identifiable and unc.identifiable
    if unc.noise is not None:
        noise = dict(unc.noise)
        widen = dict(zip(list(MODEL) + free, noise.pop("widening")))
        result.interval_noise = {**noise, "band_rad": float(window.noise_rad), "widening": widen}
    units = {"alpha0": "rad", "CO": "s^-1"}
    for j, n in enumerate(free, start=4):
        v, se = float(x[idx[j]]), float(unc.stderr[j])
        result.structure[n] = {
            "value": v, "stderr": se, "ci95": [v - Z95 * se, v + Z95 * se], "unit": units[n],
            "source": "estimated from the curve" + (f" (profile over {ALPHA0_GRID[0]:.2f}–{ALPHA0_GRID[-1]:.2f} "
                                                    "of the stroke, then a joint fit)" if n == "alpha0"
                                                    else " (joint fit)"),
            "correlation": {m: round(float(unc.correlation[j, i]), 4) for i, m in enumerate(names) if i != j}}
        if x[idx[j]] <= lower[idx[j]] + 1e-9 or x[idx[j]] >= upper[idx[j]] - 1e-9:
            result.warnings.append(f"the estimated {n} sits on the edge of its search range: the curve "
                                   "does not show it")
    result.evaluations += int(evaluations)
    shown = ", ".join(f"{n} = {result.structure[n]['value']:.4g} ± {Z95 * result.structure[n]['stderr']:.2g} "
                      f"{units[n]}" for n in free)
    result.warnings.append(f"unknown design: {shown} estimated from the curve; the uncertainty this adds "
                           "is included in the confidence intervals")
    return _with(breaker, x[4], x[5])


def characteristics_in_record_unit(capture, operation: str, window: FitWindow, result, breaker: Breaker) -> dict:
    """The characteristics of the travel as recorded (mm; speeds in m/s), from the record's mm
    channel and the breaker's mapping (``capture.meta["travel_map"]``)."""
    info = capture.meta["travel_map"]
    name = capture.meta.get("travel_channel")
    chans = [a for a in capture.aux if a.kind == "travel" and a.name == name]
    from ..breaker_travel import mm_at

    # The travel as recorded; a stored capture keeps only rad, mapped back with the same points.
    mm = np.asarray(chans[0].data if chans else mm_at(info, capture.travel), dtype=float)
    closed_mm = float(mm_at(info, 0.0))
    open_mm = float(mm_at(info, breaker.stroke))
    sign = 1.0 if open_mm > closed_mm else -1.0
    from_closed = sign * (mm - closed_mm)  # mm from closed, rising on opening
    stroke_mm = abs(open_mm - closed_mm)
    alpha0 = result.structure.get("alpha0", {}).get("value", breaker.alpha0)
    alpha0_mm = abs(float(mm_at(info, alpha0)) - closed_mm)
    c = travel_characteristics(capture.t, from_closed, operation, stroke=stroke_mm, t_start=window.t_start,
                               alpha0=alpha0_mm)
    out = {}
    for k, v in c.items():
        if k.endswith("_rad_s"):
            out[k.replace("_rad_s", "_m_s")] = float(v) * 1e-3  # mm/s -> m/s
        elif k.endswith("_rad"):
            out[k.replace("_rad", "_mm")] = float(v)
        else:
            out[k] = float(v)
    out["stroke_mm"] = stroke_mm
    out["alpha0_mm"] = alpha0_mm
    out["channel"] = name
    return out
