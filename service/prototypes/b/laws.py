"""Force laws of prototype B: scalar functions of the state, one per physical element.

Sign convention: every torque is a generalised force on the coordinate it is written for, in
that coordinate's positive direction (opening coordinate θ: rad from closed; closing
coordinate θ2: rad from open). Resisting elements therefore return negative values for positive
speeds. Each dissipative law also returns its dissipated power [W], so the energy books close.
Scalar ``math`` is used on purpose: the ODE right-hand sides call these thousands of times.
"""

from __future__ import annotations

import bisect
import math

from .mechanism import PUFFER_FILL_PRESSURE, Effects, Mechanism

SLIP_SPEED = 0.005  # regularisation of sign(ω) in Coulomb laws [rad/s]
NOZZLE_OPEN_FACTOR = 8.0  # puffer leak area after / before the nozzle clears [-]
NOZZLE_OPEN_SPAN = 0.08   # contact travel over which the nozzle throat clears [rad]


def _sign(v: float) -> float:
    """Smooth sign(v); |sign| > 0.99 above 2.7·SLIP_SPEED."""
    return math.tanh(v / SLIP_SPEED)


class Laws:
    """The mechanism's force laws with an effect setting baked in.

    Parameters
    ----------
    mech : Mechanism
    eff : Effects
    """

    def __init__(self, mech: Mechanism, eff: Effects):
        self.m = mech
        self.e = eff
        S = mech.stroke
        # Linkage ratio, mean-corrected so that L(0) = 0 and L(stroke) = stroke.
        k = eff.link_k
        self._lk = k
        self._lmean = (eff.link_a1 * (math.sin(k * S + eff.link_phi1) - math.sin(eff.link_phi1)) / k
                       + eff.link_a2 * (math.sin(2 * k * S + eff.link_phi2) - math.sin(eff.link_phi2))
                       / (2 * k)) / S
        self.linkage_on = eff.link_a1 != 0.0 or eff.link_a2 != 0.0
        self.buffer_bite = mech.alpha0 + eff.buffer_free
        # Wedge stiffness giving the requested peak wipe torque (max of q(1 - q²) is 2/(3√3)).
        self._wipe_k = eff.wipe_peak / (2 / (3 * math.sqrt(3)) * eff.wipe_width) if eff.wipe_width > 0 else 0.0
        self._knots = list(mech.cam_knots)
        self._coef = mech.cam_coefficients
        self._cam_top = self.cam(mech.cam_knots[-1])[0]
        self.gas_on = eff.gas_area > 0.0

    # --- springs -----------------------------------------------------------------------
    def _nonlinear(self, which: str) -> float:
        return self.e.spring_gamma if self.e.spring_which == which else 0.0

    def opening_spring_force(self, x: float) -> float:
        """Opening-spring force [N] at compression x [m]: kO·x·(1 + γ·(x/xO1)^p)."""
        g = self._nonlinear("opening")
        return self.m.kO * x * (1.0 + g * (x / self.m.xO1) ** self.e.spring_power)

    def opening_spring_energy(self, x: float) -> float:
        """Energy stored in the opening spring [J] at compression x [m]."""
        g, p = self._nonlinear("opening"), self.e.spring_power
        return self.m.kO * (0.5 * x * x + g * x ** (p + 2) / ((p + 2) * self.m.xO1 ** p))

    def closing_spring_force(self, x: float) -> float:
        """Closing-spring force [N] at compression x [m]: kC·x·(1 + γ·(x/xC0)^p)."""
        g = self._nonlinear("closing")
        return self.m.kC * x * (1.0 + g * (x / self.m.xC0) ** self.e.spring_power)

    def closing_spring_torque(self, th1: float) -> float:
        """Camshaft driving torque [N m] at camshaft angle θ1 [rad] (paper Eq. 2 lever)."""
        m = self.m
        c = math.cos(th1)
        x = m.xC0 - m.rC * (1.0 - c)
        return self.closing_spring_force(x) * m.rC * m.d * math.sin(th1) / (m.d + m.rC * c)

    # --- friction ----------------------------------------------------------------------
    def coulomb(self, w: float, level: float) -> tuple[float, float]:
        """Resistance torque TOf/TCf on the coordinate and its power: (torque [N m], power [W]).

        As in the paper it is a constant torque against the operation's direction; the
        Stribeck effect turns a share of it into Coulomb friction (sign of ω, Stribeck rise at
        low speed), which is what lets the mechanism stick at the end of the stroke.
        """
        e = self.e
        share = e.coulomb_share
        T = -(1.0 - share) * level
        if share:
            mag = share * level
            if e.stribeck_rise:
                mag *= 1.0 + e.stribeck_rise * math.exp(-(abs(w) / e.stribeck_speed) ** e.stribeck_shape)
            T -= mag * _sign(w)
        return T, -T * w

    def viscous(self, theta: float, w: float) -> tuple[float, float]:
        """Position-dependent viscous torque at opening angle θ [rad]: (torque, power)."""
        if not self.e.viscous:
            return 0.0, 0.0
        c = self.e.viscous * (1.0 + self.e.viscous_slope * (theta / self.m.stroke - 0.5))
        return -c * w, c * w * w

    # --- buffer (opening coordinate) ----------------------------------------------------
    def buffer(self, theta: float, w: float) -> tuple[float, float, float]:
        """Buffer torque past the bite angle: (conservative torque, damping torque, power)."""
        m, e = self.m, self.e
        s = theta - self.buffer_bite
        if s <= 0.0:
            return 0.0, 0.0, 0.0
        T_spring = -m.kb * m.rb * m.rb * s
        v = m.rb * w
        if e.buffer_exponent == 1.0 and e.buffer_metering == 0.0:
            F = m.cb * v
        else:
            area = max(1.0 - e.buffer_metering * min(s / e.buffer_span, 1.0), 0.2)
            F = (m.cb * e.buffer_vref * (abs(v) / e.buffer_vref) ** e.buffer_exponent
                 * math.copysign(1.0, v) / (area * area))
        return T_spring, -F * m.rb, F * v

    def buffer_energy(self, theta: float) -> float:
        """Energy in the buffer's stiffness [J]."""
        s = theta - self.buffer_bite
        return 0.5 * self.m.kb * self.m.rb ** 2 * s * s if s > 0 else 0.0

    # --- linkage -----------------------------------------------------------------------
    def linkage(self, theta: float) -> tuple[float, float, float]:
        """Contact position L(θ) [rad eq.], ratio ρ = dL/dθ [-] and dρ/dθ at opening angle θ."""
        e = self.e
        if not self.linkage_on:
            return theta, 1.0, 0.0
        k = self._lk
        a1, a2, p1, p2 = e.link_a1, e.link_a2, e.link_phi1, e.link_phi2
        L = (theta + a1 * (math.sin(k * theta + p1) - math.sin(p1)) / k
             + a2 * (math.sin(2 * k * theta + p2) - math.sin(p2)) / (2 * k) - self._lmean * theta)
        rho = 1.0 + a1 * math.cos(k * theta + p1) + a2 * math.cos(2 * k * theta + p2) - self._lmean
        drho = -a1 * k * math.sin(k * theta + p1) - 2 * a2 * k * math.sin(2 * k * theta + p2)
        return L, rho, drho

    # --- puffer (contact coordinate, opening) -------------------------------------------
    def puffer(self, y: float, v: float, mass: float) -> tuple[float, float, float, float]:
        """Puffer: (force on y [N m per rad], linear-damper power, gas power [W], d(mass)/dt [1/s]).

        ``mass`` is the gas mass in the cylinder relative to its initial value.
        """
        m, e = self.m, self.e
        F = -m.caec * m.raec * m.raec * v
        P_lin = -F * v
        if not self.gas_on:
            return F, P_lin, 0.0, 0.0
        vol = max(1.0 - y / (e.gas_ratio * m.stroke), 0.05)
        dens = mass / vol
        dp = dens ** e.gas_kappa - 1.0  # (p - p0)/p0
        Fg = -m.raec * e.gas_area * PUFFER_FILL_PRESSURE * dp
        # The nozzle throat clears the fixed contact at gas_clear: the leak area then grows
        # NOZZLE_OPEN_FACTOR-fold over NOZZLE_OPEN_SPAN (the puffer discharges into the arc zone).
        u = min(max((y - e.gas_clear) / NOZZLE_OPEN_SPAN, 0.0), 1.0)
        leak = e.gas_leak * (1.0 + (NOZZLE_OPEN_FACTOR - 1.0) * u * u * (3.0 - 2.0 * u))
        dmass = -leak * math.sqrt(dens) * dp / math.sqrt(abs(dp) + 1e-4)
        return F + Fg, P_lin, -Fg * v, dmass

    def gas_pressure(self, y: float, mass: float) -> float:
        """(p - p0)/p0 in the puffer [-]."""
        vol = max(1.0 - y / (self.e.gas_ratio * self.m.stroke), 0.05)
        return (mass / vol) ** self.e.gas_kappa - 1.0

    # --- contact wipe (contact coordinate, closing) -------------------------------------
    def wipe(self, y2: float, v2: float) -> tuple[float, float, float]:
        """Contact wipe past the touch position: (wedge force, friction force, friction power)."""
        e = self.e
        dlt = y2 - e.wipe_touch
        if dlt <= 0.0 or (e.wipe_peak == 0.0 and e.wipe_friction == 0.0):
            return 0.0, 0.0, 0.0
        q = math.tanh(dlt / e.wipe_width)
        Fk = -self._wipe_k * e.wipe_width * q * (1.0 - q * q)
        Ff = -e.wipe_friction * q * _sign(v2)
        return Fk, Ff, -Ff * v2

    def wipe_energy(self, y2: float) -> float:
        """Energy stored in the contact fingers [J]."""
        e = self.e
        dlt = y2 - e.wipe_touch
        if dlt <= 0.0:
            return 0.0
        q = math.tanh(dlt / e.wipe_width)
        return 0.5 * self._wipe_k * e.wipe_width ** 2 * q * q

    # --- cam ---------------------------------------------------------------------------
    def cam(self, th1: float) -> tuple[float, float, float]:
        """h, h', h'' of the cam at camshaft angle θ1 [rad] (dwell outside the table)."""
        x = self._knots
        if th1 <= x[0]:
            return self._coef[0][3], 0.0, 0.0
        if th1 >= x[-1]:
            c = self._coef[-1]
            s = x[-1] - x[-2]
            return ((c[0] * s + c[1]) * s + c[2]) * s + c[3], 0.0, 0.0
        k = bisect.bisect_right(x, th1) - 1
        c = self._coef[k]
        s = th1 - x[k]
        return (((c[0] * s + c[1]) * s + c[2]) * s + c[3],
                (3 * c[0] * s + 2 * c[1]) * s + c[2],
                6 * c[0] * s + 2 * c[1])

    def cam_efficiency(self, th1: float) -> float:
        """Cam-roller efficiency η(θ1) [-]: 1 - loss·(1 + slope·(2u - 1)), u along the rise."""
        e, m = self.e, self.m
        if not e.cam_loss:
            return 1.0
        u = min(max((th1 - m.cam_rise_start) / (m.cam_rise_end - m.cam_rise_start), 0.0), 1.0)
        return 1.0 - e.cam_loss * (1.0 + e.cam_slope * (2.0 * u - 1.0))

    # --- latch and sensor ---------------------------------------------------------------
    def latch(self, t: float) -> float:
        """Share of the driving torque the latch has released at time t [s] (1 = free)."""
        if self.e.latch_ramp <= 0.0 or t >= self.e.latch_ramp:
            return 1.0
        s = max(t, 0.0) / self.e.latch_ramp
        return s * s * (3.0 - 2.0 * s)

    def sensor_error(self, theta):
        """Travel-transducer error [rad] at true travel θ [rad from closed] (array-safe)."""
        import numpy as np

        e = self.e
        theta = np.asarray(theta, dtype=float)
        if e.sensor_kind == "polynomial":
            u = theta / self.m.stroke
            return e.sensor_amp * ((1.0 - e.sensor_shape) * u * u + e.sensor_shape * u ** 3)
        if e.sensor_kind == "eccentric":
            return e.sensor_amp * (np.sin(theta + e.sensor_shape) - math.sin(e.sensor_shape))
        return np.zeros_like(theta)
