"""Prototype F: opening of the reference 252 kV spring mechanism, written blind from Yan et al. 2026.

State: output-shaft travel theta [rad] from the closed position (rises during opening). All torques
are divided by J2, so every term is an angular acceleration [s^-2]. With every effect at 0 the
equation of motion is exactly the paper's reduced opening model (Eq. 11):

    theta'' = BO - AO*theta - CO*theta'                               (theta < alpha0)
    theta'' = BO - AO*theta - CO*theta' - DO*theta' - EO*(theta-alpha0) (theta >= alpha0)

with AO = kO rO^2/J2, BO = (kO xO1 rO - TOf)/J2, CO = caec raec^2/J2, DO = cb rb^2/J2,
EO = kb rb^2/J2. A stiff end stop at THETA_STOP (beyond the healthy stroke, so inactive in the
reduced model) limits the travel. Effects and what strength 1.0 means: see EFFECTS / docs.
"""

from __future__ import annotations

import math

import numpy as np

FS = 128_000.0
DT = 1.0 / FS
PRE_S = 0.020            # pre-trigger idle
DUR_S = 0.100            # capture length (healthy peak ~57 ms after motion start)
LATCH_LEAD_S = 0.0004    # latch shock before motion
THETA_STOP = 1.10        # end stop [rad]
K_STOP = 4.0e6           # end-stop stiffness [s^-2]
C_STOP = 800.0           # end-stop damping [s^-1]

# design values, from reference-252kV.toml (Table 1 with xC0 change, irrelevant to opening)
kO, xO1, rO, J2, TOf = 130e3, 0.17, 0.08, 0.243, 600.0
caec, raec, cb, kb, rb, ALPHA0 = 1000.0, 0.15, 1500.0, 150e3, 0.08, 0.698
DESIGN = {
    "AO": kO * rO**2 / J2,
    "BO": (kO * xO1 * rO - TOf) / J2,
    "CO": caec * raec**2 / J2,
    "DO": cb * rb**2 / J2,
    "EO": kb * rb**2 / J2,
    "alpha0": ALPHA0,
}
FRICTION_DESIGN = TOf / J2  # friction part of BO [s^-2]

CATALOGUE = ("linkage_kinematics", "orifice_buffer", "puffer_gas", "rod_elasticity",
             "stribeck_friction", "viscous_friction", "spring_nonlinearity", "sensor_nonlinearity")
OUTSIDE = "transducer_lag"
EFFECTS = {
    "linkage_kinematics": "spring crank arm r(theta) = rO*(1 + 0.12*s*(theta - 0.5)): the "
                          "transmission ratio changes by 12 % over the 1 rad stroke at s=1",
    "orifice_buffer": "buffer damping force DO*v_ref*|v/v_ref|^n*sign(v), n = 1 + 0.8*s "
                      "(n = 1.8 at s=1), v_ref = 15 rad/s",
    "puffer_gas": "adiabatic puffer pressure torque s*260*((1/(1-0.5*theta))^1.4 - 1) s^-2 "
                  "(about 9 % of the spring torque at full stroke at s=1)",
    "rod_elasticity": "compliant pull rod between the shaft (0.6 J2, spring, friction, buffer, "
                      "transducer) and the contact (0.4 J2, puffer): rod mode 150/sqrt(s) Hz, "
                      "5 % damping; s < 0.02 is rigid",
    "stribeck_friction": "friction (TOf/J2)*(1 + 0.6*s*exp(-(v/2 rad/s)^2)): 60 % extra "
                         "static friction at s=1, falling to Coulomb with speed",
    "viscous_friction": "extra linkage friction 45*s*theta' s^-2 (about half of CO at s=1)",
    "spring_nonlinearity": "spring force kO*x*(1 + 0.15*s*((x/xO1)^2 - 1)), x the compression: "
                           "about -11 % force at the open position at s=1",
    "sensor_nonlinearity": "reading = theta + 0.012*s*sin(pi*theta): 12 mrad bow at mid-stroke",
    "transducer_lag": "(outside the catalogue) first-order transducer lag, tau = 0.5*s ms",
}


def _accel(th, v, p, e):
    """Angular acceleration of the (rigid) shaft, all effects in e (dict of strengths)."""
    AO, BO, CO, DO, EO, a0 = p["AO"], p["BO"], p["CO"], p["DO"], p["EO"], p["alpha0"]
    fr = p.get("friction", FRICTION_DESIGN)
    spring_const = BO + fr  # = kO xO1 rO / J2
    s_lk = e.get("linkage_kinematics", 0.0)
    s_sn = e.get("spring_nonlinearity", 0.0)
    if s_lk == 0.0 and s_sn == 0.0:
        a = spring_const - AO * th
    else:
        eps = 0.12 * s_lk
        ratio = 1.0 + eps * (th - 0.5)                     # r(theta)/rO
        defl = th + eps * (0.5 * th * th - 0.5 * th)         # integral of ratio = (xO1 - x)/rO
        xr = 1.0 - (AO / spring_const) * defl                # x/xO1 (AO/spring_const = rO/xO1)
        f = spring_const * xr * (1.0 + 0.15 * s_sn * (xr * xr - 1.0))
        a = f * ratio
    a -= fr
    a -= CO * v
    s = e.get("stribeck_friction", 0.0)
    if s:
        a -= fr * 0.6 * s * math.exp(-(v / 2.0) ** 2)
    s = e.get("viscous_friction", 0.0)
    if s:
        a -= 45.0 * s * v
    s = e.get("puffer_gas", 0.0)
    if s:
        a -= s * 260.0 * ((1.0 / (1.0 - 0.5 * min(th, 1.6))) ** 1.4 - 1.0)
    if th >= a0:
        s = e.get("orifice_buffer", 0.0)
        if s:
            n = 1.0 + 0.8 * s
            a -= DO * 15.0 * math.copysign(abs(v / 15.0) ** n, v)
        else:
            a -= DO * v
        a -= EO * (th - a0)
    if th > THETA_STOP:
        a -= K_STOP * (th - THETA_STOP) + C_STOP * max(v, 0.0)
    return a


def simulate(p: dict, effects: dict | None = None, n: int | None = None):
    """Shaft travel theta [rad] at 128 kHz from motion start (index 0 = t 0), n samples.

    Fixed-step RK4 at the sample rate. Returns (theta, t_alpha0_index, t_peak_index).
    """
    e = {k: float(v) for k, v in (effects or {}).items() if float(v) != 0.0}
    n = n or int(round((DUR_S - PRE_S) * FS))
    h = DT
    s_rod = e.get("rod_elasticity", 0.0)
    out = np.empty(n)
    if s_rod < 0.02:
        th, v = 0.0, 0.0
        for i in range(n):
            out[i] = th
            k1v = _accel(th, v, p, e); k1x = v
            k2v = _accel(th + 0.5 * h * k1x, v + 0.5 * h * k1v, p, e); k2x = v + 0.5 * h * k1v
            k3v = _accel(th + 0.5 * h * k2x, v + 0.5 * h * k2v, p, e); k3x = v + 0.5 * h * k2v
            k4v = _accel(th + h * k3x, v + h * k3v, p, e); k4x = v + h * k3v
            th += h / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v += h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
    else:
        out = _simulate_rod(p, e, n, s_rod)
    return out


def _simulate_rod(p, e, n, s_rod):
    fm, fc = 0.6, 0.4
    w = 2 * math.pi * 150.0 / math.sqrt(s_rod)
    K = w * w / (1.0 / fm + 1.0 / fc)          # rod stiffness / J2
    C = 2 * 0.05 * w / (1.0 / fm + 1.0 / fc)
    CO = p["CO"]
    pm = dict(p, CO=0.0)                        # puffer acts on the contact side
    eg = dict(e); sg = eg.pop("puffer_gas", 0.0)

    def f(y):
        th, v, tc, vc = y
        rod = K * (tc - th) + C * (vc - v)
        am = (_accel(th, v, pm, eg) + rod) / fm
        gas = sg * 260.0 * ((1.0 / (1.0 - 0.5 * min(tc, 1.6))) ** 1.4 - 1.0) if sg else 0.0
        ac = (-CO * vc - gas - rod) / fc
        return np.array([v, am, vc, ac])

    y = np.zeros(4)
    out = np.empty(n)
    h = DT
    for i in range(n):
        out[i] = y[0]
        k1 = f(y); k2 = f(y + 0.5 * h * k1); k3 = f(y + 0.5 * h * k2); k4 = f(y + h * k3)
        y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return out


def sensor(theta: np.ndarray, effects: dict | None = None) -> np.ndarray:
    """What the travel transducer reads (noise-free)."""
    e = effects or {}
    r = np.asarray(theta, dtype=float).copy()
    s = float(e.get("sensor_nonlinearity", 0.0))
    if s:
        r = r + 0.012 * s * np.sin(np.pi * r)
    s = float(e.get(OUTSIDE, 0.0))
    if s:
        tau = 0.5e-3 * s
        a = DT / (tau + DT)
        y = np.empty_like(r); acc = r[0]
        for i in range(len(r)):
            acc += a * (r[i] - acc); y[i] = acc
        r = y
    return r
