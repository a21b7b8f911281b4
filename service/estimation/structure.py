"""An unknown design's structure, estimated from the opening curve itself: the buffer
engagement angle α0 (``[unknown_design] estimate = ["alpha0"]``).

α0 is first located by a profile: the fitted parameters are carried by least squares along a
grid of α0 values (each step starting from the previous one's answer), and the α0 of least
residual is kept. A joint least-squares step then frees α0 with the model parameters, and the
covariance of the joint fit gives every CI, so the uncertainty α0 adds is in the CIs.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..mechanics.breaker import Breaker
from ..mechanics.characteristics import travel_characteristics
from .curves import OpeningCurves
from .polish import batched_jacobian, polish
from .uncertainty import Z95, covariance
from .window import FitWindow, block_samples, decimate

# α0 profile grid, as fractions of the stroke: buffers engage in the last half of the opening
# stroke (the paper's reference: 0.70); 0.30–0.98 leaves room on both sides.
ALPHA0_GRID = np.linspace(0.30, 0.98, 35)
NAMES = ("AO", "BO", "DO", "EO", "alpha0", "tau")


def _rows_factory(window: FitWindow, breaker: Breaker, settings):
    grid = decimate(window.t, window.y, block_samples(settings.block_open, window.sample_rate))
    w = grid.weight[None, :]

    def rows(X):
        X = np.atleast_2d(X)
        out = np.empty((X.shape[0], grid.t.size))
        for i, x in enumerate(X):
            curves = OpeningCurves(dataclasses.replace(breaker, alpha0=float(x[4])), grid)
            out[i] = w[0] * (curves.full(np.array([[x[0], x[1], x[2], x[3], x[5]]]))[0] - grid.y)
        return out

    return rows


def fit_alpha0(result, window: FitWindow, breaker: Breaker, settings) -> Breaker:
    """Estimate α0 for an opening ``result`` fitted at the breaker file's α0; update ``result``
    (parameters, CIs from the joint covariance, ``structure``) and return the breaker with the
    estimated α0."""
    rows = _rows_factory(window, breaker, settings)
    p = result.parameters
    x = np.array([p["AO"], p["BO"], p["DO"], p["EO"], breaker.alpha0, result.onset_delay_s])
    lo_tau, hi_tau = window.tau_range or (0.0, settings.tau_max)
    stroke = breaker.stroke
    lower = np.array([1.0, 1.0, 0.0, 0.0, ALPHA0_GRID[0] * stroke, lo_tau])
    upper = np.array([1e6, 1e6, 1e4, 1e6, ALPHA0_GRID[-1] * stroke, hi_tau])
    scale = np.array([3000.0, 5000.0, 30.0, 5000.0, 0.05 * stroke, 1e-3])
    keep = [0, 1, 2, 3, 5]

    def at_alpha(a, x0):
        fixed = lambda X: rows(np.insert(np.atleast_2d(X), 4, a, axis=1))  # noqa: E731
        pol = polish(fixed, x0[keep], lower[keep], upper[keep], scale[keep], max_nfev=20)
        xf = np.insert(pol.x, 4, a)
        return xf, float(np.sum(rows(xf[None, :]) ** 2))

    # Profile from the file's α0 outwards (continuation keeps each start in its basin).
    grid = ALPHA0_GRID * stroke
    start = int(np.argmin(np.abs(grid - breaker.alpha0)))
    sse = np.full(grid.size, np.inf)
    sols = [None] * grid.size
    for order in (range(start, grid.size), range(start - 1, -1, -1)):
        xc = x.copy()
        for k in order:
            xc, sse[k] = at_alpha(grid[k], xc)
            sols[k] = xc
    best = int(np.argmin(sse))
    x = sols[best]
    pol = polish(rows, x, lower, upper, scale, max_nfev=60)
    if float(np.sum(rows(pol.x[None, :]) ** 2)) <= sse[best]:
        x = pol.x
    jac = batched_jacobian(rows, x, scale, lower, upper)[1]
    unc = covariance(jac, window.noise_rad, scale, n_model=5)
    for i, n in enumerate(NAMES[:4]):
        result.parameters[n] = float(x[i])
        result.stderr[n] = float(unc.stderr[i])
        result.ci95[n] = (float(x[i] - Z95 * unc.stderr[i]), float(x[i] + Z95 * unc.stderr[i]))
    result.onset_delay_s = float(x[5])
    keep_c = [0, 1, 2, 3, 5]
    result.correlation = unc.correlation[np.ix_(keep_c, keep_c)].tolist()
    result.identifiable = result.identifiable and unc.identifiable
    se = float(unc.stderr[4])
    on_edge = x[4] <= lower[4] + 1e-9 or x[4] >= upper[4] - 1e-9
    result.structure["alpha0"] = {
        "value": float(x[4]), "stderr": se, "ci95": [float(x[4] - Z95 * se), float(x[4] + Z95 * se)],
        "unit": "rad", "source": "estimated from the curve (profile over "
        f"{ALPHA0_GRID[0]:.2f}–{ALPHA0_GRID[-1]:.2f} of the stroke, then a joint fit)",
        "correlation": {n: round(float(unc.correlation[4, i]), 4) for i, n in enumerate(NAMES) if i != 4}}
    result.evaluations += int(grid.size * 20 + 60)
    result.warnings.append(f"unknown design: α0 = {x[4]:.3f} ± {Z95 * se:.3f} rad estimated from the curve; "
                           "its uncertainty is included in the confidence intervals")
    if on_edge:
        result.warnings.append("the estimated α0 sits on the edge of its search range: the buffer engagement "
                               "is not visible in this curve")
    return dataclasses.replace(breaker, alpha0=float(x[4]))


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
