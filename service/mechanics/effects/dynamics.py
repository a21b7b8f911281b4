"""Equations of motion of the virtual prototype: the reduced models (Eqs. 7 and 11) plus the
catalogued effects, as one right-hand side per operation in "per J2" units.

State x = [θ, θ', φ, φ'] for an opening (output shaft and contact side) and
x = [θ1, θ1', φ, φ'] for a closing (camshaft and contact side). With a rigid rod the contact
side moves with the shaft (φ = θ or θ2), so the same state layout serves every case.

These functions are compiled once and shared by the exact integrator (scipy ``solve_ivp``) and
the fast fixed-step RK4 used inside the diagnosis fits.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from service.mechanics.closing_kernel import cam_at
from .cam_friction import cam_load_factor
from .contact_wipe import wipe_torque
from .linkage_kinematics import inertia_ratio
from .orifice_buffer import orifice_torque
from .puffer_gas import gas_torque, leaky_gas
from .rod_elasticity import MASS_FRACTION, rod_coefficients
from .spring_nonlinearity import closing_spring_factor, opening_spring_extra
from .stribeck_friction import stribeck_torque
from .viscous_friction import viscous_torque

# Indices into the strength vector (order of effects.EFFECT_NAMES).
LINKAGE, ORIFICE, PUFFER, ROD, STRIBECK, VISCOUS, SPRING, SENSOR, CAM, WIPE = range(10)
# Shape parameters follow the strengths: effect k's j-th shape is e[10 + 3k + j] (effects.SHAPES).
SHAPE0, NSH = 10, 3

# Opening constants c: [CO s^-1, α0 rad, X1 = xO1/rO rad, stroke rad]
# Closing constants c: [xC0 m, rC m, d m, θ1_start rad, CO s^-1, g_start m, θt rad, θ2_end rad,
#                       θm rad, rise_end rad]


@njit(cache=True, inline="always")
def _sh(e, k, j):
    return e[SHAPE0 + NSH * k + j]


@njit(cache=True, inline="always")
def _gas(theta, omega, e, BO, stroke):
    return gas_torque(theta, e[PUFFER], BO, stroke, _sh(e, PUFFER, 0), _sh(e, PUFFER, 1))


@njit(cache=True)
def opening_rhs(x, p, e, c):
    """d/dt of the opening state; p = [AO, BO, DO, EO], e = strengths, c = constants."""
    dx = np.empty(4)
    _opening_into(x, p, e, c, dx)
    return dx


@njit(cache=True)
def _opening_into(x, p, e, c, dx):
    """``opening_rhs`` written into ``dx`` (no allocation: the RK4 calls it ~10⁴ times a curve)."""
    AO, BO, DO, EO = p[0], p[1], p[2], p[3]
    CO, alpha0, X1, stroke = c[0], c[1], c[2], c[3]
    th, om, ph, vp = x[0], x[1], x[2], x[3]
    # Generalised torque on the output shaft, per J2 [rad/s²].
    q = -AO * th + BO + opening_spring_extra(th, e[SPRING], AO, X1, _sh(e, SPRING, 0))
    q -= stribeck_torque(om, e[STRIBECK], BO, _sh(e, STRIBECK, 0), _sh(e, STRIBECK, 1))
    q -= viscous_torque(om, e[VISCOUS], CO, _sh(e, VISCOUS, 0), th / stroke)
    if th > alpha0:
        q -= DO * om + EO * (th - alpha0) + orifice_torque(th, om, e[ORIFICE], DO, alpha0, stroke,
                                                           _sh(e, ORIFICE, 0), _sh(e, ORIFICE, 1),
                                                           _sh(e, ORIFICE, 2))
    if e[ROD] > 0.0:
        K, C = rod_coefficients(e[ROD], _sh(e, ROD, 0))
        f = K * (th - ph) + C * (om - vp)
        mu = MASS_FRACTION
        dx[0] = om
        dx[1] = (q - f) / (1.0 - mu)
        dx[2] = vp
        dx[3] = (f - CO * vp - _gas(ph, vp, e, BO, stroke)) / mu
    else:
        j, jp = inertia_ratio(th, e[LINKAGE], 0.5 * stroke, _sh(e, LINKAGE, 0), _sh(e, LINKAGE, 1))
        leak = _sh(e, PUFFER, 2)
        if e[PUFFER] > 0.0 and leak > 0.0:
            # the contact-side slot is free with a rigid rod: it carries the gas over-density
            gas, dg = leaky_gas(th, om, ph, e[PUFFER], BO, stroke, _sh(e, PUFFER, 0), _sh(e, PUFFER, 1), leak)
        else:
            gas, dg = _gas(th, om, e, BO, stroke), om
        q -= CO * j * om + gas
        acc = (q - 0.5 * jp * om * om) / j
        dx[0] = om
        dx[1] = acc
        dx[2] = dg
        dx[3] = acc


@njit(cache=True)
def closing_rhs(x, p, e, c, cx, cy, cc):
    """d/dt of the closing state; p = [AC, BC, CC, DC]; cx, cy, cc: the cam spline."""
    dx = np.empty(4)
    _closing_into(x, p, e, c, cx, cy, cc, dx)
    return dx


@njit(cache=True)
def _closing_into(x, p, e, c, cx, cy, cc, dx):
    """``closing_rhs`` written into ``dx``."""
    AC, BC, CC, DC = p[0], p[1], p[2], p[3]
    xC0, rC, d, CO, g_start = c[0], c[1], c[2], c[4], c[5]
    tt, te, tm = c[6], c[7], c[8]
    th1, om1, ph, vp = x[0], x[1], x[2], x[3]
    h, h1, h2, _k = cam_at(th1, 0, cx, cy, cc)
    ct = math.cos(th1)
    g = (xC0 - rC * (1.0 - ct)) * math.sin(th1) / (d + rC * ct)
    h0 = 2.0 * tm - te
    u = (h - h0) / (te - h0)
    share = _sh(e, SPRING, 1)
    drive = AC * g * closing_spring_factor(th1, (1.0 - share) * e[SPRING], xC0, rC, _sh(e, SPRING, 0))
    drive -= stribeck_torque(om1, e[STRIBECK], AC * g_start, _sh(e, STRIBECK, 0), _sh(e, STRIBECK, 1))
    B = BC * cam_load_factor(e[CAM], _sh(e, CAM, 0), min(max(u, 0.0), 1.0))
    om2 = h1 * om1
    load = CC + DC * h + viscous_torque(om2, e[VISCOUS], CO, _sh(e, VISCOUS, 0), u)
    if share > 0.0 and e[SPRING] != 0.0:
        # the opening spring being charged by the closing, with the same family of stiffening
        load += share * e[SPRING] * DC * te * max(u, 0.0) ** _sh(e, SPRING, 0)
    if e[WIPE] > 0.0:
        tt = h0 + _sh(e, WIPE, 0) * (te - h0)
    if e[ROD] > 0.0:
        K, C = rod_coefficients(e[ROD], _sh(e, ROD, 0))
        mu = MASS_FRACTION
        f = K * (h - ph) + C * (om2 - vp)
        acc1 = (drive - B * h1 * ((1.0 - mu) * h2 * om1 * om1 + load + f)) / (1.0 + B * (1.0 - mu) * h1 * h1)
        dx[0] = om1
        dx[1] = acc1
        dx[2] = vp
        dx[3] = (f - wipe_torque(ph, vp, e[WIPE], CC, tt, te, _sh(e, WIPE, 1))) / mu
    else:
        j, jp = inertia_ratio(h, e[LINKAGE], tm, _sh(e, LINKAGE, 0), _sh(e, LINKAGE, 1))
        load += wipe_torque(h, om2, e[WIPE], CC, tt, te, _sh(e, WIPE, 1))
        acc1 = (drive - B * h1 * ((j * h2 + 0.5 * jp * h1 * h1) * om1 * om1 + load)) / (1.0 + B * j * h1 * h1)
        dx[0] = om1
        dx[1] = acc1
        dx[2] = om2
        dx[3] = h1 * acc1 + h2 * om1 * om1


@njit(cache=True)
def _rhs(op, x, p, e, c, cx, cy, cc):
    if op == 0:
        return opening_rhs(x, p, e, c)
    return closing_rhs(x, p, e, c, cx, cy, cc)


@njit(cache=True, inline="always")
def _rhs_into(op, x, p, e, c, cx, cy, cc, dx):
    if op == 0:
        _opening_into(x, p, e, c, dx)
    else:
        _closing_into(x, p, e, c, cx, cy, cc, dx)


@njit(cache=True)
def _rk4_step(op, x, hs, p, e, c, cx, cy, cc):
    out = np.empty(4)
    w = np.empty((5, 4))
    _rk4_into(op, x, hs, p, e, c, cx, cy, cc, out, w)
    return out


@njit(cache=True)
def _rk4_into(op, x, hs, p, e, c, cx, cy, cc, out, w):
    """One RK4 step from ``x`` written into ``out``; ``w`` (5 × 4) the stages' work space. The
    same arithmetic, in the same order, as the array form x + hs·(k1 + 2k2 + 2k3 + k4)/6."""
    k1, k2, k3, k4, xt = w[0], w[1], w[2], w[3], w[4]
    _rhs_into(op, x, p, e, c, cx, cy, cc, k1)
    for i in range(4):
        xt[i] = x[i] + 0.5 * hs * k1[i]
    _rhs_into(op, xt, p, e, c, cx, cy, cc, k2)
    for i in range(4):
        xt[i] = x[i] + 0.5 * hs * k2[i]
    _rhs_into(op, xt, p, e, c, cx, cy, cc, k3)
    for i in range(4):
        xt[i] = x[i] + hs * k3[i]
    _rhs_into(op, xt, p, e, c, cx, cy, cc, k4)
    for i in range(4):
        out[i] = x[i] + hs * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) / 6.0


@njit(cache=True, nogil=True)
def integrate_rk4(op, x0, p, e, c, cx, cy, cc, t, dt_max):
    """Fixed-step RK4 with steps landing on every ``t`` (non-decreasing, from 0) [s].

    Returns the shaft angle and speed at ``t`` (opening θ; closing θ2 = h(θ1)) and the event
    times [s]: ev[0] buffer engagement / contact touch, ev[1] end of the valid interval
    (maximum opening angle / end of cam rise), ev[2] = 1.0 if a closing stalled.
    """
    m = t.size
    theta = np.empty(m)
    omega = np.empty(m)
    ev = np.array([np.nan, np.nan, 0.0])
    x = x0.copy()
    xn = np.empty(4)
    xm = np.empty(4)
    w = np.empty((5, 4))
    tc = 0.0
    alpha = c[1] if op == 0 else c[6]
    rise_end = c[9] if op == 1 else 0.0
    for j in range(m):
        tj = t[j]
        if tj > tc:
            nsub = max(int(math.ceil((tj - tc) / dt_max - 1e-9)), 1)  # a sub-ulp gap is one tiny step
            hs = (tj - tc) / nsub
            for _ in range(nsub):
                _rk4_into(op, x, hs, p, e, c, cx, cy, cc, xn, w)
                # Restart the step at a switch of the equations (buffer engagement, contact
                # touch) so that no RK4 step straddles a jump in the acceleration.
                sw = 0 if op == 0 else 2
                if x[sw] <= alpha < xn[sw]:
                    h1s = hs * (alpha - x[sw]) / (xn[sw] - x[sw])
                    for _it in range(2):
                        _rk4_into(op, x, h1s, p, e, c, cx, cy, cc, xm, w)
                        v = (xm[sw + 1] if xm[sw + 1] > 0.0 else 1.0)
                        h1s = min(max(h1s - (xm[sw] - alpha) / v, 0.0), hs)
                    _rk4_into(op, x, h1s, p, e, c, cx, cy, cc, xm, w)
                    xm[sw] = max(xm[sw], alpha * (1.0 + 1e-15) + 1e-300)
                    _rk4_into(op, xm, hs - h1s, p, e, c, cx, cy, cc, xn, w)
                if op == 0:
                    if math.isnan(ev[0]) and x[0] <= alpha < xn[0]:
                        ev[0] = tc + hs * (alpha - x[0]) / (xn[0] - x[0])
                    if math.isnan(ev[1]) and not math.isnan(ev[0]) and x[1] > 0.0 >= xn[1]:
                        ev[1] = tc + hs * x[1] / (x[1] - xn[1])
                else:
                    if math.isnan(ev[0]) and x[2] < alpha <= xn[2]:
                        ev[0] = tc + hs * (alpha - x[2]) / (xn[2] - x[2])
                    if math.isnan(ev[1]) and x[0] < rise_end <= xn[0]:
                        ev[1] = tc + hs * (rise_end - x[0]) / (xn[0] - x[0])
                    if math.isnan(ev[1]) and xn[1] <= 0.0:
                        ev[2] = 1.0
                x, xn = xn, x      # swap the buffers: xn is written afresh by the next step
                tc += hs
            tc = tj
        side = _sh(e, ROD, 1) if e[ROD] > 0.0 else 0.0  # sensor on the contact side of the rod
        if op == 0:
            theta[j] = x[0] + side * (x[2] - x[0])
            omega[j] = x[1] + side * (x[3] - x[1])
        else:
            h, h1, _h2, _k = cam_at(x[0], 0, cx, cy, cc)
            theta[j] = h + side * (x[2] - h)
            omega[j] = h1 * x[1] + side * (x[3] - h1 * x[1])
    return theta, omega, ev
