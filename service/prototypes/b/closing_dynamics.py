"""Closing of prototype B: the closing spring turns the camshaft, the cam drives the output shaft.

θ1 is the camshaft angle [rad], θ2 = h(θ1) the output-shaft angle in the closing coordinate
(0 = open). Newton's law on each shaft, with the cam-roller torque T12 eliminated and a cam
efficiency η (the camshaft supplies T21 = h'·T12/η):

    J2 shaft:   J_eq·θ2'' + ½·dJ_eq/dθ2·θ2'² = T12 - Q2
    camshaft:   J1·θ1'' = T_C(θ1) - h'·T12/η
    =>  (J1 + J_eq·h'²/η)·θ1'' = T_C - (h'/η)·(J_eq·h''·θ1'² + ½·dJ_eq/dθ2·h'²·θ1'² + Q2)

Q2 collects the loads on the output shaft: opening spring, Coulomb/viscous friction and the
contact-side loads seen through the linkage ratio. With a compliant pull rod the contact is a
second body (J_contact, position y2) and only J_mech rides on the cam. When the cam reaches its
dwell the output shaft is held by the closing latch; a compliant contact keeps moving.
"""

from __future__ import annotations

import numpy as np

from .laws import Laws
from .mechanism import Effects, Mechanism
from .motion import Motion, Segment, integrate
from .opening_dynamics import rod_constants


def simulate_closing_b(mech: Mechanism, eff: Effects, t_end: float) -> Motion:
    """Integrate one closing from latch release for ``t_end`` seconds.

    ``sample(t)`` gives per time [s since latch release]: ``travel`` (sensor side, rad from
    closed, before sensor errors), ``theta2`` (output shaft, closing coordinate), ``contact``,
    ``theta1``, ``spring_work`` (work of the closing spring [J]), ``opening_spring_stored``,
    ``kinetic``, ``stored``, ``dissipated`` [J].
    """
    laws = Laws(mech, eff)
    S = mech.stroke
    Jm, Jc, J1 = mech.J_mech, mech.J_contact, mech.J1
    rod = eff.rod_hz is not None
    k_rod, c_rod = rod_constants(mech, eff) if rod else (0.0, 0.0)

    def link2(th2):
        """Contact position in the closing coordinate, ratio and dρ/dθ2."""
        L, rho, drho = laws.linkage(S - th2)
        return S - L, rho, -drho

    def shaft_loads(th2, w2):
        """Loads on the output shaft in the closing direction, as resisting torque and power."""
        Ts = laws.opening_spring_force(mech.xO0 + mech.rO * th2) * mech.rO
        Tf, Pf = laws.coulomb(w2, mech.TCf)
        Tv, Pv = laws.viscous(S - th2, w2)
        return Ts - Tf - Tv, Pf + Pv

    def cam_phase(t, x, with_rod):
        th1, w1 = x[0], x[1]
        h, h1, h2 = laws.cam(th1)
        w2 = h1 * w1
        eta = laws.cam_efficiency(th1)
        Tc = laws.closing_spring_torque(th1)
        lr = laws.latch(t)
        Q2, P2 = shaft_loads(h, w2)
        y2c, rho, drho = link2(h)
        if with_rod:
            y2, v2 = x[2], x[3]
            dv = rho * w2 - v2
            Fr = k_rod * (y2c - y2) + c_rod * dv
            Q2 += rho * Fr
            J, dJ = Jm, 0.0
            Fk, Ff, Pw = laws.wipe(y2, v2)
            acc_c = (Fr + Fk + Ff) / Jc
            P2 += Pw + c_rod * dv * dv
        else:
            Fk, Ff, Pw = laws.wipe(y2c, rho * w2)
            Q2 -= rho * (Fk + Ff)
            P2 += Pw
            J, dJ = Jm + Jc * rho * rho, 2.0 * Jc * rho * drho
        inertial = J * h2 * w1 * w1 + 0.5 * dJ * h1 * h1 * w1 * w1
        acc1 = (lr * Tc - (h1 / eta) * (inertial + Q2)) / (J1 + J * h1 * h1 / eta)
        T12 = J * (h1 * acc1 + h2 * w1 * w1) + 0.5 * dJ * w2 * w2 + Q2
        P_cam = (1.0 / eta - 1.0) * T12 * w2
        P_latch = (1.0 - lr) * Tc * w1
        out = [w1, acc1]
        if with_rod:
            out += [x[3], acc_c]
        return out + [P2 + P_cam + P_latch, lr * Tc * w1 + P_latch]

    def rhs_cam(t, x):
        return cam_phase(t, x, rod)

    x0 = [mech.theta1_start, 0.0] + ([0.0, 0.0] if rod else []) + [0.0, 0.0]

    def latch_event(t, x):
        return x[0] - mech.cam_rise_end
    latch_event.direction = 1.0

    seg, hit, x = integrate(rhs_cam, np.array(x0), 0.0, t_end, {"latched": latch_event}, "cam")
    segments = [seg]
    events = {}
    h_top = laws.cam(mech.cam_rise_end)[0]
    if hit:
        events["latched"] = seg.t1
        y2c, rho, _ = link2(h_top)
        if rod:
            def rhs_held(t, z):
                y2, v2 = z[0], z[1]
                Fr = k_rod * (y2c - y2) - c_rod * v2
                Fk, Ff, Pw = laws.wipe(y2, v2)
                return [v2, (Fr + Fk + Ff) / Jc, Pw + c_rod * v2 * v2]
            z0 = np.array([x[2], x[3], x[4]])
            if seg.t1 < t_end:
                seg2, _, _ = integrate(rhs_held, z0, seg.t1, t_end, {}, "held")
                segments.append(seg2)
        elif seg.t1 < t_end:
            segments.append(Segment(seg.t1, t_end, None, np.array([x[-2]]), "held"))
    touch = _touch_time(segments[0], laws, link2, rod, eff)
    if touch is not None:
        events["touch"] = touch

    def observe(sg, t):
        n = t.size
        if sg.mode == "cam":
            X = sg.sol(t)
            th1, w1 = X[0], X[1]
            cams = [laws.cam(v) for v in th1]
            th2 = np.array([c[0] for c in cams])
            w2 = np.array([c[1] for c in cams]) * w1
            links = [link2(v) for v in th2]
            y2c = np.array([a[0] for a in links])
            rho = np.array([a[1] for a in links])
            if rod:
                y2, v2 = X[2], X[3]
                kinetic = 0.5 * J1 * w1 * w1 + 0.5 * Jm * w2 * w2 + 0.5 * Jc * v2 * v2
                stored_rod = 0.5 * k_rod * (y2c - y2) ** 2
            else:
                y2 = y2c
                kinetic = 0.5 * J1 * w1 * w1 + 0.5 * (Jm + Jc * rho * rho) * w2 * w2
                stored_rod = np.zeros(n)
            dissipated, work = X[-2], X[-1]
        else:
            th1 = np.full(n, np.nan)
            th2 = np.full(n, h_top)
            y2c = np.full(n, link2(h_top)[0])
            work = np.full(n, np.nan)
            kinetic = np.full(n, np.nan)
            if sg.sol is not None:
                Z = sg.sol(t)
                y2, dissipated = Z[0], Z[2]
                stored_rod = 0.5 * k_rod * (y2c - y2) ** 2
            else:
                y2 = y2c
                dissipated = np.full(n, sg.state[0])
                stored_rod = np.zeros(n)
        x_open = mech.xO0 + mech.rO * th2
        U_open = np.array([laws.opening_spring_energy(v) for v in x_open]) - laws.opening_spring_energy(mech.xO0)
        stored = stored_rod + np.array([laws.wipe_energy(v) for v in y2])
        sensed = y2 if (rod and eff.sensor_side == "contact") else y2c
        return {"travel": S - sensed, "theta2": th2, "contact": y2, "theta1": th1,
                "spring_work": work, "opening_spring_stored": U_open, "kinetic": kinetic,
                "stored": stored, "dissipated": dissipated}

    return Motion("close", segments, events, observe, t_end,
                  {"rod_stiffness": k_rod, "rod_damping": c_rod})


def _touch_time(seg, laws, link2, rod, eff):
    """First instant the contact reaches the touch position [s], or None."""
    t = np.linspace(seg.t0, seg.t1, 2000)
    X = seg.sol(t)
    if rod:
        y2 = X[2]
    else:
        y2 = np.array([link2(laws.cam(v)[0])[0] for v in X[0]])
    above = np.nonzero(y2 >= eff.wipe_touch)[0]
    return float(t[above[0]]) if above.size else None
