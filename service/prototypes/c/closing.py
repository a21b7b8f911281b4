"""Prototype C, closing: the closing spring drives the camshaft (theta1), the cam drives the output
shaft (closing coordinate theta2 = h(theta1) = 1 - travel) and recharges the opening spring.

Lagrange with the cam as a holonomic constraint (theta1 the coordinate; kinetic energy
J1 w1^2/2 + J_r(theta2) (h' w1)^2/2, J_r the rigid output-shaft side):
    (J1 + (1+mu) h'^2 J_r) w1' = T_C(theta1) - c1 w1
                                 - (1+mu) h' [J_r h'' w1^2 + J_r,2 (h' w1)^2 / 2 + T_load - T_rod]
    J_e psi' = T_rod - ... (contact side in theta2, when the pull rod is elastic)
T_load = opening spring kO (xO0 + theta2 rO) rO + TCf (+ friction effects); mu is cam-roller friction
(share of the transmitted torque). With every effect at 0 this is the paper's reduced closing model
(Eq. 12): (1 + BC h'^2) theta1'' = AC g(theta1) - BC h' (h'' w1^2 + CC + DC theta2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from . import effects as fx
from .mechanism import cam, closing_lever

EPS_W = 0.02                 # [rad/s] speed over which signed friction turns on (tanh)
RTOL, ATOL = 1e-9, 1e-11
HORIZON = 0.25               # [s] after release: the cam must have reached its top by then


@dataclass
class ClosingModel:
    """A closing's right-hand side for one unit and condition set."""

    c: dict
    s: dict
    sh: dict
    friction: float = 1.0   # the capture's friction condition (scales cam friction)

    def __post_init__(self):
        c, s = self.c, self.s
        self.cam = cam()
        self.rod = s.get("rod_elasticity", 0.0) > 0
        if self.rod:
            self.Jr0, self.Je, self.K, self.C = fx.rod_params(c["J2"], s["rod_elasticity"], self.sh["rod_elasticity"])
        else:
            self.Jr0, self.Je, self.K, self.C = c["J2"], 0.0, 0.0, 0.0
        self.n = 4 if self.rod else 2
        sv = s.get("viscous_friction", 0.0)
        self.cv2 = fx.viscous_coeff(c["TOf"], sv, self.sh["viscous_friction"]) if sv else 0.0
        self.cv1 = self.cv2 * self.sh["viscous_friction"]["camshaft_ratio"] if sv else 0.0
        self.ramp = (s.get("latch_ramp", 0.0) * self.sh["latch_ramp"]["ramp_ms"] * 1e-3
                     if s.get("latch_ramp") else 0.0)
        self.x_closing = (c["xC0"] - 2 * c["rC"], c["xC0"])

    def y0(self) -> np.ndarray:
        y = np.zeros(self.n)
        y[0] = self.c["theta1_start"]
        if self.rod:
            y[2] = float(self.cam.h(y[0]))
        return y

    def drive(self, q, t):
        """Closing-spring torque on the camshaft [N m]."""
        x, lever = closing_lever(q, self.c)
        sh = self.sh.get("spring_nonlinearity", {})
        F = fx.spring_force(self.c["kC"], x, *self.x_closing, self.s.get("spring_nonlinearity", 0.0),
                            sh.get("gamma_closing", 0.0), sh.get("width", 1.0))
        r = 1.0 if self.ramp == 0.0 else min(1.0, max(t, 0.0) / self.ramp)
        return F * lever * r

    def load(self, th2, w2):
        """Opening-spring and friction torque resisting closing on the output shaft [N m]."""
        c = self.c
        sh = self.sh.get("spring_nonlinearity", {})
        x = c["xO0"] + th2 * c["rO"]
        T = fx.spring_force(c["kO"], x, c["xO0"], c["xO1"], self.s.get("spring_nonlinearity", 0.0),
                            sh.get("gamma_opening", 0.0), sh.get("width", 1.0)) * c["rO"]
        s = self.s.get("stribeck_friction", 0.0)
        if s > 0:
            st = self.sh["stribeck_friction"]
            ratio = x / (0.5 * (c["xO0"] + c["xO1"]))
            g = fx.stribeck_factor(w2, ratio, s, st) - (1.0 - s * st["load_share"])
            T += c["TCf"] * (1.0 - s * st["load_share"]) + c["TCf"] * g * math.tanh(w2 / EPS_W)
        else:
            T += c["TCf"]
        return T + self.cv2 * w2

    def rhs(self, t, y):
        q, w = y[0], y[1]
        cm = self.cam
        H, H1, H2 = cm.eval3(q)
        w2 = H1 * w
        lam, dlam = fx.linkage_inertia(1.0 - H, self.s.get("linkage_kinematics", 0.0),
                                       self.sh.get("linkage_kinematics"))
        Jr, dJr2 = self.Jr0 * lam, -self.Jr0 * dlam          # d(J_r)/d(theta2) = -d/d(travel)
        mu = fx.cam_mu(H2, cm.d2h_max, self.s.get("cam_friction", 0.0), self.sh.get("cam_friction")) * self.friction
        dy = np.empty(self.n)
        Trod = 0.0
        if self.rod:
            ph, ps = y[2], y[3]
            Trod = self.K * (ph - H) + self.C * (ps - w2)
            Tw = fx.contact_torque(1.0 - ph, ps, self.s.get("contact_wipe", 0.0), self.sh.get("contact_wipe"))
            dy[2], dy[3] = ps, (-Trod - Tw) / self.Je
        else:
            Trod = -fx.contact_torque(1.0 - H, w2, self.s.get("contact_wipe", 0.0), self.sh.get("contact_wipe"))
        T12_rest = Jr * H2 * w * w + 0.5 * dJr2 * w2 * w2 + self.load(H, w2) - Trod
        M = self.c["J1"] + (1.0 + mu) * H1 * H1 * Jr
        dy[0] = w
        dy[1] = (self.drive(q, t) - self.cv1 * w - (1.0 + mu) * H1 * T12_rest) / M
        return dy


def integrate(model: ClosingModel, *, method: str = "DOP853", rtol=RTOL, atol=ATOL):
    """Integrate from latch release until the camshaft reaches the cam top (end of stroke).

    Returns (solution, t_end [s from release]).
    """
    top = model.cam.theta1_end

    def end(t, y):
        return y[0] - top
    end.terminal, end.direction = True, 1

    sol = solve_ivp(model.rhs, (0.0, HORIZON), model.y0(), method=method, rtol=rtol, atol=atol,
                    dense_output=True, events=[end], max_step=2e-4)
    if sol.status != 1:
        raise RuntimeError(f"the closing did not reach the closed position within {HORIZON} s "
                           f"({sol.message})")
    return sol, float(sol.t[-1])


def travel(model: ClosingModel, sol, t_end: float, times: np.ndarray) -> np.ndarray:
    """Shaft travel [rad from closed] at ``times`` [s from release]; held closed after the end."""
    tt = np.clip(times, 0.0, t_end)
    q = sol.sol(tt)[0]
    out = 1.0 - model.cam.h(q)
    out[times <= 0.0] = 1.0 - float(model.cam.h(model.c["theta1_start"]))
    return out
