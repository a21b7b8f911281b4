"""Prototype D's equations of motion: the opening and the closing of one unit, fixed-step RK4.

Coordinates. The output shaft's angle θ [rad] is the travel, measured from the closed position
(opening coordinate). The closing works in the paper's closing coordinate θ2 = stroke − θ [rad]
driven through the cam θ2 = h(θ1 − φ) by the camshaft angle θ1 [rad]. The contact side (pull rod,
moving contact, puffer cylinder) is a mass m_c [kg] at position x [m] along its stroke, driven by
the shaft through a linkage x = X(θ) with ratio G(θ) = dX/dθ [m/rad].

Opening (rigid rod, no play):
    J(θ) θ̈ + m_c G G′ θ̇² = T_s(θ) − T_f(θ̇) − T_b(θ, θ̇) − G·F_c(X, Gθ̇, p) − T_L(t),
    J(θ) = J_s + m_c G(θ)²,
with the opening spring torque T_s, friction T_f, the buffer T_b (engaged past α0), the
contact-side force F_c (arc-chamber damping, puffer gas pressure p) and the latch torque T_L.
Closing (rigid rod, no play), power balance across the cam with T12 the cam torque on the shaft:
    J1 θ̈1 = T_cs(θ1) − (h′ + c_cam) T12 − T_L(t),
    T12 = J(θ2) θ̈2 + ½ J′(θ2) θ̇2² + T_Cf + T_os(θ2) + T_f(θ̇2) + G·F_w(y, ẏ),
    θ2 = h,  θ̇2 = h′θ̇1,  θ̈2 = h″θ̇1² + h′θ̈1.
With a compliant rod or play in a pin, the contact side is its own degree of freedom, coupled
through the force F = k·dz(X(θ) − x) + c·(…) (dz: the dead zone of the play).
With every effect off (G ≡ G0, no gas, no play, linear springs, constant friction, instant latch)
these are exactly the paper's Eq. 11 and Eqs. 2–7 with J2 = J_s + m_c G0².

Every function here is compiled by numba; the parameter vector's layout is ``INDEX``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

NAMES = (
    # common: inertias, linkage, friction, coupling, latch, driving spring
    "J_s", "m_c", "G0", "s_link", "T_fric", "dT_stribeck", "w_stribeck", "c_visc",
    "k_cpl", "c_cpl", "gap", "tau_latch", "k_spring", "e_spring", "x_lo", "x_hi",
    # opening: spring, arc-chamber damping, buffer, puffer
    "xO1", "rO", "c_aec_x", "alpha0", "rb", "cb", "kb", "s_orifice", "v_ref",
    "A_p", "A_n", "p0", "gamma", "rho0", "L0", "Cd",
    # closing: closing spring crank, opening spring charged, camshaft, cam friction, wipe
    "xC0", "rC", "d", "kO", "xO0", "J1", "c_cam", "cam_phase",
    "F_wipe", "mu_wipe", "tan_chamfer", "l_chamfer", "theta2_touch", "stroke",
)
INDEX = {name: i for i, name in enumerate(NAMES)}
(_J_S, _M_C, _G0, _S_LINK, _T_FRIC, _DT_STRIBECK, _W_STRIBECK, _C_VISC, _K_CPL, _C_CPL, _GAP,
    _TAU_LATCH, _K_SPRING, _E_SPRING, _X_LO, _X_HI, _XO1, _RO, _C_AEC_X, _ALPHA0, _RB, _CB, _KB,
    _S_ORIFICE, _V_REF, _A_P, _A_N, _P0, _GAMMA, _RHO0, _L0, _CD, _XC0, _RC, _D, _KO, _XO0, _J1,
    _C_CAM, _CAM_PHASE, _F_WIPE, _MU_WIPE, _TAN_CHAMFER, _L_CHAMFER, _THETA2_TOUCH,
    _STROKE) = range(len(NAMES))

STRIBECK_REVERSAL_RAD_S = 0.05  # below this reverse speed the breakaway friction turns over


def pack(values: dict) -> np.ndarray:
    """The parameter vector from ``{name: value}``; names not given are 0 (effect off)."""
    unknown = set(values) - set(INDEX)
    if unknown:
        raise ValueError(f"unknown prototype-D parameter(s): {', '.join(sorted(unknown))}")
    vec = np.zeros(len(NAMES))
    for name, value in values.items():
        vec[INDEX[name]] = float(value)
    return vec


@njit(cache=True)
def linkage(th, P):
    """(X [m], G [m/rad], G′ [m/rad²]) of the crank linkage at travel θ [rad].

    G = G0 (1 + s (cos(θ − ½) − c̄)), a crank swinging ±0.5 rad about its perpendicular, with
    c̄ = 2 sin ½ the mean of the cosine over the 1 rad stroke so the stroke ratio stays G0."""
    g0 = P[_G0]
    s = P[_S_LINK]
    cbar = 2.0 * math.sin(0.5)
    G = g0 * (1.0 + s * (math.cos(th - 0.5) - cbar))
    X = g0 * (th + s * (math.sin(th - 0.5) + math.sin(0.5) - cbar * th))
    Gp = -g0 * s * math.sin(th - 0.5)
    return X, G, Gp


@njit(cache=True)
def friction(w, P):
    """Friction torque [N m] opposing the driven direction at shaft speed w [rad/s]: the reduced
    model's constant torque, the Stribeck excess exp(−(w/w_s)²) and the viscous part c·w."""
    if w >= 0.0:
        sigma = 1.0
    else:
        sigma = max(-1.0, 1.0 + 2.0 * w / STRIBECK_REVERSAL_RAD_S)
    stribeck = 0.0
    if P[_DT_STRIBECK] != 0.0:
        stribeck = P[_DT_STRIBECK] * math.exp(-(w / P[_W_STRIBECK]) ** 2) * sigma
    return P[_T_FRIC] + stribeck + P[_C_VISC] * w


@njit(cache=True)
def spring_force(x, P):
    """Driving-spring force [N] at compression x [m]: k x plus the coil-contact term
    e k (x_hi − x_lo) u², u = (x − x_lo)/(x_hi − x_lo) (e > 0 progressive, < 0 degressive)."""
    span = P[_X_HI] - P[_X_LO]
    u = (x - P[_X_LO]) / span
    return P[_K_SPRING] * (x + P[_E_SPRING] * span * u * u)


@njit(cache=True)
def coupling(delta, ddelta, P):
    """Force [N] the linkage puts on the contact side for a stretch δ [m] (rate δ̇ [m/s]) of
    the pull rod, with a play of width ``gap`` centred on zero (no force inside it)."""
    half = 0.5 * P[_GAP]
    if delta > half:
        return P[_K_CPL] * (delta - half) + P[_C_CPL] * ddelta
    if delta < -half:
        return P[_K_CPL] * (delta + half) + P[_C_CPL] * ddelta
    return 0.0


@njit(cache=True)
def latch(t, P, T0):
    """Torque [N m] the releasing latch still holds t [s] after release: a linear ramp over
    tau_latch from the static holding torque T0, or nothing when the release is instant."""
    tau = P[_TAU_LATCH]
    if tau <= 0.0 or t >= tau:
        return 0.0
    return T0 * (1.0 - t / tau)


@njit(cache=True)
def puffer_flow(p, P):
    """Nozzle flow out of the puffer [m³/s] at absolute pressure p [Pa] (negative: gas flows
    back in): orifice flow Cd A_n √(2|Δp|/ρ), ρ = ρ0 (p/p0)^(1/γ) along the isentrope."""
    dp = p - P[_P0]
    rho = P[_RHO0] * (p / P[_P0]) ** (1.0 / P[_GAMMA])
    q = P[_CD] * P[_A_N] * math.sqrt(2.0 * abs(dp) / rho)
    return q if dp >= 0.0 else -q


@njit(cache=True)
def open_contact_force(x, v, p, P):
    """Force [N] resisting the contact side in opening: the arc chamber's linear damping and
    the puffer's gas overpressure on the piston area."""
    return P[_C_AEC_X] * v + P[_A_P] * (p - P[_P0])


@njit(cache=True)
def open_rhs(t, y, P, T0):
    """d/dt of (θ, θ̇, x, ẋ, p) in an opening (see the module docstring)."""
    th, w, x, v, p = y[0], y[1], y[2], y[3], y[4]
    X, G, Gp = linkage(th, P)
    T = P[_RO] * spring_force(P[_XO1] - th * P[_RO], P) - friction(w, P) - latch(t, P, T0)
    if th > P[_ALPHA0]:
        vb = P[_RB] * w
        damp = P[_CB] * vb
        if P[_S_ORIFICE] != 0.0:
            damp *= abs(vb / P[_V_REF]) ** P[_S_ORIFICE]
        T -= P[_RB] * (damp + P[_KB] * P[_RB] * (th - P[_ALPHA0]))
    out = np.zeros(5)
    if P[_K_CPL] == 0.0:  # rigid rod, no play: the contact side rides on the shaft
        xc, vc = X, G * w
        acc = (T - G * open_contact_force(xc, vc, p, P) - P[_M_C] * G * Gp * w * w) / (
            P[_J_S] + P[_M_C] * G * G)
        out[2] = vc
    else:
        xc, vc = x, v
        f = coupling(X - x, G * w - v, P)
        acc = (T - G * f) / P[_J_S]
        out[2] = v
        out[3] = (f - open_contact_force(x, v, p, P)) / P[_M_C]
    if th <= 0.0 and w <= 0.0 and acc < 0.0:  # resting on the closed stop
        acc = 0.0
    out[0] = w
    out[1] = acc
    if P[_A_P] != 0.0:
        vol = P[_A_P] * (P[_L0] - xc)
        out[4] = P[_GAMMA] * p * (P[_A_P] * vc - puffer_flow(p, P)) / vol
    return out


@njit(cache=True)
def cam_lookup(th1, table):
    """(h, h′, h″) at camshaft angle θ1 [rad] from the uniform table (Hermite in h and h′);
    past the table's ends the profile is flat."""
    lo = table[0, 0]
    step = table[1, 0] - lo
    n = table.shape[0]
    if th1 <= lo:
        return table[0, 1], 0.0, 0.0
    if th1 >= table[n - 1, 0]:
        return table[n - 1, 1], 0.0, 0.0
    f = (th1 - lo) / step
    i = min(int(f), n - 2)
    s = f - i
    h00 = (1 + 2 * s) * (1 - s) ** 2
    h10 = s * (1 - s) ** 2
    h01 = s * s * (3 - 2 * s)
    h11 = s * s * (s - 1)
    h = h00 * table[i, 1] + h10 * step * table[i, 2] + h01 * table[i + 1, 1] + h11 * step * table[i + 1, 2]
    hp = h00 * table[i, 2] + h10 * step * table[i, 3] + h01 * table[i + 1, 2] + h11 * step * table[i + 1, 3]
    hpp = (1 - s) * table[i, 3] + s * table[i + 1, 3]
    return h, hp, hpp


@njit(cache=True)
def closing_spring_torque(th1, P):
    """Closing-spring torque on the camshaft [N m] (paper Eq. 2's geometry):
    F(x) rC d sin θ1 / (d + rC cos θ1), compression x = xC0 − rC (1 − cos θ1)."""
    x = P[_XC0] - P[_RC] * (1.0 - math.cos(th1))
    return spring_force(x, P) * P[_RC] * P[_D] * math.sin(th1) / (P[_D] + P[_RC] * math.cos(th1))


@njit(cache=True)
def wipe_force(y, v, P):
    """Force [N] of the fixed fingers on the moving contact y [m] into its closing stroke:
    past touch the fingers' normal force rises over the chamfer, which pushes back with
    F_n tan α; sliding friction μ F_n opposes the motion."""
    X1, _, _ = linkage(P[_STROKE], P)
    Xt, _, _ = linkage(P[_STROKE] - P[_THETA2_TOUCH], P)
    into = y - (X1 - Xt)
    if P[_F_WIPE] == 0.0 or into <= 0.0:
        return 0.0
    ramp = min(1.0, into / P[_L_CHAMFER])
    fn = P[_F_WIPE] * ramp
    sigma = math.tanh(v / 0.01)  # sliding friction, regularised below 1 cm/s
    chamfer = P[_TAN_CHAMFER] if into < P[_L_CHAMFER] else 0.0
    return fn * (P[_MU_WIPE] * sigma + chamfer)


@njit(cache=True)
def close_rhs(t, y, P, T0, table):
    """d/dt of (θ1, θ̇1, y, ẏ) in a closing (see the module docstring)."""
    th1, w1, yc, vc = y[0], y[1], y[2], y[3]
    h, hp, hpp = cam_lookup(th1 - P[_CAM_PHASE], table)
    th2 = h
    w2 = hp * w1
    X1, _, _ = linkage(P[_STROKE], P)
    X, G, Gp = linkage(P[_STROKE] - th2, P)  # G(θ) at θ = stroke − θ2; dG/dθ2 = −G′
    Y = X1 - X
    R = friction(w2, P) + P[_KO] * (P[_XO0] + th2 * P[_RO]) * P[_RO]
    out = np.zeros(4)
    if P[_K_CPL] == 0.0:
        J = P[_J_S] + P[_M_C] * G * G
        dJ = -2.0 * P[_M_C] * G * Gp
        R += G * wipe_force(Y, G * w2, P) + 0.5 * dJ * w2 * w2
        out[2] = G * w2
    else:
        J = P[_J_S]
        f = coupling(Y - yc, G * w2 - vc, P)
        R += G * f
        out[2] = vc
        out[3] = (f - wipe_force(yc, vc, P)) / P[_M_C]
    drive = closing_spring_torque(th1, P) - latch(t, P, T0)
    c = P[_C_CAM] * min(1.0, max(hp, 0.0) / 0.05)  # only where the cam lifts the roller
    acc = (drive - (hp + c) * (J * hpp * w1 * w1 + R)) / (P[_J1] + (hp + c) * J * hp)
    if c != 0.0 and J * (hpp * w1 * w1 + hp * acc) + R < 0.0:  # the roller pulls: friction turns
        c = -c
        acc = (drive - (hp + c) * (J * hpp * w1 * w1 + R)) / (P[_J1] + (hp + c) * J * hp)
    out[0] = w1
    out[1] = acc
    return out


@njit(cache=True)
def _rk4(rhs_kind, y0, P, T0, table, dt, n):
    """n fixed RK4 steps of dt [s] from y0 at t = 0 (latch release); rows of the states."""
    out = np.empty((n + 1, y0.size))
    y = y0.copy()
    out[0] = y
    for k in range(n):
        t = k * dt
        if rhs_kind == 0:
            k1 = open_rhs(t, y, P, T0)
            k2 = open_rhs(t + dt / 2, y + dt / 2 * k1, P, T0)
            k3 = open_rhs(t + dt / 2, y + dt / 2 * k2, P, T0)
            k4 = open_rhs(t + dt, y + dt * k3, P, T0)
        else:
            k1 = close_rhs(t, y, P, T0, table)
            k2 = close_rhs(t + dt / 2, y + dt / 2 * k1, P, T0, table)
            k3 = close_rhs(t + dt / 2, y + dt / 2 * k2, P, T0, table)
            k4 = close_rhs(t + dt, y + dt * k3, P, T0, table)
        y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[k + 1] = y
    return out


def integrate_open(P: np.ndarray, dt: float, n: int) -> np.ndarray:
    """The opening's states (θ [rad], θ̇ [rad/s], x [m], ẋ [m/s], p [Pa]) at t = k·dt [s]
    after latch release, k = 0…n, from rest in the closed position."""
    X0, G0, _ = linkage(0.0, P)
    y0 = np.array([0.0, 0.0, X0 + P[_GAP] / 2, 0.0, P[_P0]])
    J0 = P[_J_S] if P[_K_CPL] else P[_J_S] + P[_M_C] * G0 * G0
    T0 = open_rhs(0.0, y0, P, 0.0)[1] * J0  # the latch holds the net static torque
    return _rk4(0, y0, P, max(T0, 0.0), np.zeros((2, 4)), dt, n)


def integrate_close(P: np.ndarray, table: np.ndarray, theta1_start: float, dt: float,
                    n: int) -> np.ndarray:
    """The closing's states (θ1 [rad], θ̇1 [rad/s], y [m], ẏ [m/s]) at t = k·dt [s] after the
    closing latch releases the camshaft at rest at theta1_start [rad], k = 0…n."""
    y0 = np.array([theta1_start, 0.0, P[_GAP] / 2, 0.0])
    T0 = close_rhs(0.0, y0, P, 0.0, table)[1] * P[_J1]  # the cam dwells at release (h′ = 0): the camshaft alone
    return _rk4(1, y0, P, max(T0, 0.0), table, dt, n)


@njit(cache=True)
def close_travel(states, P, table):
    """(travel θ = stroke − h [rad], its rate [rad/s]) from the closing's states. Once the
    shaft reaches the closed position (the cam's dwell at its top) the trip latch holds it
    there, whatever the camshaft does after."""
    n = states.shape[0]
    th, w = np.empty(n), np.empty(n)
    top = table[table.shape[0] - 1, 1]
    latched = False
    for k in range(n):
        if latched:
            th[k] = th[k - 1]
            w[k] = 0.0
            continue
        h, hp, _ = cam_lookup(states[k, 0] - P[_CAM_PHASE], table)
        th[k] = P[_STROKE] - h
        w[k] = -hp * states[k, 1]
        latched = h >= top - 1e-9 * abs(top)
    return th, w
