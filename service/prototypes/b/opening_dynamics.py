"""Opening of prototype B: the output shaft driven by the opening spring, written in torques.

Rigid pull rod (one degree of freedom, θ = output-shaft angle from closed [rad]):

    d/dt[J(θ)·θ'] - ½·J'(θ)·θ'² = T_spring + T_coulomb + T_viscous + T_buffer + ρ(θ)·F_contact
    J(θ) = J_mech + J_contact·ρ(θ)²,  ρ = dL/dθ (linkage ratio, 1 when the linkage is ideal)

Compliant pull rod (two degrees of freedom, θ and the contact position y [rad eq.]):

    J_mech·θ''   = T_spring + T_coulomb + T_viscous + T_buffer - ρ(θ)·F_rod
    J_contact·y'' = F_rod + F_contact,   F_rod = k_rod·(L(θ) - y) + c_rod·(ρ·θ' - y')

The mechanism-side loads (spring, friction, buffer) act on θ; the puffer acts on the contact.
Extra states integrate the dissipated energy [J], the work done on the puffer gas [J] and the
relative gas mass in the puffer [-], so the energy books can be checked.
"""

from __future__ import annotations

import math

import numpy as np

from .laws import Laws
from .mechanism import Effects, Mechanism
from .motion import Motion, integrate


def rod_constants(mech: Mechanism, eff: Effects) -> tuple[float, float]:
    """Rod stiffness [N m/rad] and damping [N m s/rad] giving ``rod_hz`` and ``rod_zeta``."""
    Jm, Jc = mech.J_mech, mech.J_contact
    Jr = Jm * Jc / (Jm + Jc)
    k = (2 * math.pi * eff.rod_hz) ** 2 * Jr
    return k, 2.0 * eff.rod_zeta * math.sqrt(k * Jr)


def simulate_opening_b(mech: Mechanism, eff: Effects, t_end: float) -> Motion:
    """Integrate one opening from rest at the closed position for ``t_end`` seconds.

    Returns a Motion whose ``sample(t)`` gives, per time [s since latch release]: ``travel``
    (sensor-side, rad from closed, before sensor errors), ``theta`` (output shaft), ``contact``,
    ``omega`` (output shaft speed), ``spring_released``, ``kinetic``, ``stored``, ``dissipated``,
    ``gas_work`` [J].
    """
    laws = Laws(mech, eff)
    Jm, Jc = mech.J_mech, mech.J_contact
    rod = eff.rod_hz is not None
    k_rod, c_rod = rod_constants(mech, eff) if rod else (0.0, 0.0)
    x_closed = mech.xO1

    def mech_loads(t, th, w):
        xs = mech.xO1 - mech.rO * th
        Ts = laws.opening_spring_force(xs) * mech.rO
        lr = laws.latch(t)
        Tf, Pf = laws.coulomb(w, mech.TOf)
        Tv, Pv = laws.viscous(th, w)
        Tbk, Tbd, Pb = laws.buffer(th, w)
        return lr * Ts + Tf + Tv + Tbk + Tbd, (1.0 - lr) * Ts * w + Pf + Pv + Pb

    def rhs_rigid(t, x):
        th, w, _, _, gm = x
        L, rho, drho = laws.linkage(th)
        Tm, Pm = mech_loads(t, th, w)
        Fc, Pc, Pg, dgm = laws.puffer(L, rho * w, gm)
        J = Jm + Jc * rho * rho
        acc = (Tm + rho * Fc - Jc * rho * drho * w * w) / J
        return [w, acc, Pm + Pc, Pg, dgm]

    def rhs_rod(t, x):
        th, w, y, v, _, _, gm = x
        L, rho, _ = laws.linkage(th)
        Tm, Pm = mech_loads(t, th, w)
        dv = rho * w - v
        Fr = k_rod * (L - y) + c_rod * dv
        Fc, Pc, Pg, dgm = laws.puffer(y, v, gm)
        return [w, (Tm - rho * Fr) / Jm, v, (Fr + Fc) / Jc, Pm + Pc + c_rod * dv * dv, Pg, dgm]

    rhs = rhs_rod if rod else rhs_rigid
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0] if rod else [0.0, 0.0, 0.0, 0.0, 1.0])
    bite = laws.buffer_bite

    def bite_event(t, x):
        return x[0] - bite

    segments, events = [], {}
    t0 = 0.0
    direction = 1.0
    for _ in range(50):
        bite_event.direction = direction
        seg, hit, x = integrate(rhs, x, t0, t_end, {"buffer": bite_event}, "open")
        segments.append(seg)
        t0 = seg.t1
        if hit is None or t0 >= t_end:
            break
        events.setdefault("buffer", t0)
        direction = -1.0 if x[1] > 0 else 1.0

    def observe(seg, t):
        X = seg.sol(t)
        th, w = X[0], X[1]
        Lrho = [laws.linkage(v) for v in th]
        L = np.array([a[0] for a in Lrho])
        rho = np.array([a[1] for a in Lrho])
        U0 = laws.opening_spring_energy(x_closed)
        released = U0 - np.array([laws.opening_spring_energy(mech.xO1 - mech.rO * v) for v in th])
        stored = np.array([laws.buffer_energy(v) for v in th])
        if rod:
            y, v = X[2], X[3]
            kinetic = 0.5 * Jm * w * w + 0.5 * Jc * v * v
            stored = stored + 0.5 * k_rod * (L - y) ** 2
            travel = y if eff.sensor_side == "contact" else L
            dissipated, gas, gm = X[4], X[5], X[6]
        else:
            y = L
            kinetic = 0.5 * (Jm + Jc * rho * rho) * w * w
            travel = L
            dissipated, gas, gm = X[2], X[3], X[4]
        return {"travel": travel, "theta": th, "contact": y, "omega": w,
                "spring_released": released, "kinetic": kinetic, "stored": stored,
                "dissipated": dissipated, "gas_work": gas, "gas_mass": gm}

    return Motion("open", segments, events, observe, t_end,
                  {"rod_stiffness": k_rod, "rod_damping": c_rod})
