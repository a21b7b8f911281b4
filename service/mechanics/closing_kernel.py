"""Compiled RK4 integrator for a population of closing parameter sets (Eq. 7).

Validated against ``scipy.integrate.solve_ivp`` on ``closing.closing_rhs`` in the tests; this
module only makes the same equations fast enough for CMA-ES.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always", error_model="numpy")
def cam_at(theta1, k, x, y, c):
    """The cam profile's cubic spline at ``theta1`` [rad]: h [rad], h' [-], h'' [1/rad] and the
    segment index (``k`` is the hint to start the search from; knots ``x``, values ``y``,
    coefficients ``c``). Flat beyond the table's ends."""
    n = x.size
    if theta1 <= x[0]:
        return y[0], 0.0, 0.0, 0
    if theta1 >= x[n - 1]:
        return y[n - 1], 0.0, 0.0, n - 2
    while k < n - 2 and theta1 >= x[k + 1]:
        k += 1
    while k > 0 and theta1 < x[k]:
        k -= 1
    s = theta1 - x[k]
    h = ((c[0, k] * s + c[1, k]) * s + c[2, k]) * s + c[3, k]
    h1 = (3.0 * c[0, k] * s + 2.0 * c[1, k]) * s + c[2, k]
    h2 = 6.0 * c[0, k] * s + 2.0 * c[1, k]
    return h, h1, h2, k


@njit(cache=True, inline="always", error_model="numpy")
def _accel(th, om, k, AC, BC, CC, DC, xC0, rC, d, x, y, c):
    h, h1, h2, k = cam_at(th, k, x, y, c)
    ct = math.cos(th)
    g = (xC0 - rC * (1.0 - ct)) * math.sin(th) / (d + rC * ct)
    return (AC * g - BC * h1 * (h2 * om * om + CC + DC * h)) / (1.0 + BC * h1 * h1), k


@njit(cache=True, error_model="numpy")
def integrate_closing_batch(P, t, tau, dt_max, xC0, rC, d, theta1_start, x, y, c, rise_end):
    n = P.shape[0]
    m = t.size
    theta2 = np.empty((n, m))
    omega2 = np.empty((n, m))
    t_peak = np.full(n, np.nan)
    stalled = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        AC, BC, CC, DC = P[i, 0], P[i, 1], P[i, 2], P[i, 3]
        th = theta1_start
        om = 0.0
        tc = 0.0
        k = 0
        for j in range(m):
            tj = t[j] - tau[i]
            if tj > tc:
                span = tj - tc
                nsub = int(math.ceil(span / dt_max - 1e-9))
                hstep = span / nsub
                for _ in range(nsub):
                    a1, k = _accel(th, om, k, AC, BC, CC, DC, xC0, rC, d, x, y, c)
                    a2, k = _accel(th + 0.5 * hstep * om, om + 0.5 * hstep * a1, k,
                                   AC, BC, CC, DC, xC0, rC, d, x, y, c)
                    a3, k = _accel(th + 0.5 * hstep * (om + 0.5 * hstep * a1), om + 0.5 * hstep * a2, k,
                                   AC, BC, CC, DC, xC0, rC, d, x, y, c)
                    a4, k = _accel(th + hstep * (om + 0.5 * hstep * a2), om + hstep * a3, k,
                                   AC, BC, CC, DC, xC0, rC, d, x, y, c)
                    th_new = th + hstep * (om + hstep * (a1 + a2 + a3) / 6.0)
                    om_new = om + hstep * (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
                    if th < rise_end <= th_new and math.isnan(t_peak[i]):
                        # Cubic Hermite on the step for the crossing instant.
                        lo, hi = 0.0, 1.0
                        for _it in range(40):
                            s = 0.5 * (lo + hi)
                            h00 = 2 * s**3 - 3 * s**2 + 1
                            h10 = s**3 - 2 * s**2 + s
                            h01 = -2 * s**3 + 3 * s**2
                            h11 = s**3 - s**2
                            val = h00 * th + h10 * hstep * om + h01 * th_new + h11 * hstep * om_new
                            if val >= rise_end:
                                hi = s
                            else:
                                lo = s
                        t_peak[i] = tc + 0.5 * (lo + hi) * hstep
                    th, om = th_new, om_new
                    tc += hstep
                    if om <= 0.0 and math.isnan(t_peak[i]) and tc > 0.0:
                        stalled[i] = True
                tc = tj
            h, h1, _h2, k = cam_at(th, k, x, y, c)
            theta2[i, j] = h
            omega2[i, j] = h1 * om
    return theta2, omega2, t_peak, stalled
