"""Prototype C, opening: output shaft (travel theta from closed) driven by the opening spring.

Equations (travel coordinate, torques on the output shaft, N m):
    J_r(theta) w' + J_r'(theta) w^2 / 2 = T_spring - T_friction - T_buffer + T_rod       (shaft side)
    J_e psi'                               = -T_rod - T_puffer                               (contact side)
with T_rod = K (phi - theta) + C (psi - w) when the pull rod is elastic (rod_elasticity), and the
contact side rigidly on the shaft otherwise (J_r = J2, T_puffer on the shaft). The buffer acts for
theta > alpha0. With every effect at 0 this is exactly the paper's reduced opening model (Eq. 8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from . import effects as fx
from .mechanism import DESIGN

# Puffer cylinder (gas model of puffer_gas): piston area and SF6 fill, typical of a 252 kV puffer.
PUFFER_AREA = 0.020          # [m^2]
P_FILL = 0.6e6               # absolute SF6 fill [Pa]
RHO_FILL = P_FILL / (56.9 * 293.0)   # SF6 density at fill [kg/m^3]; R = 8.314/0.146 J/(kg K)
P_EPS = 500.0                # [Pa] regularises the orifice law's sqrt at zero pressure difference
EPS_W = 0.02                 # [rad/s] speed over which signed friction turns on (tanh)
RTOL, ATOL = 1e-9, 1e-11
PEAK_SPEED = 0.05            # [rad/s] nearly stopped: the peak is then found within PEAK_SEARCH
PEAK_SEARCH = 0.002          # [s]; with signed friction the shaft may creep instead of reversing
HORIZON = 0.25               # [s] after release: the stroke must have peaked by then


@dataclass
class OpeningModel:
    """An opening's right-hand side for one unit and condition set (built by ``build``)."""

    c: dict
    s: dict
    sh: dict
    puffer_scale: float
    omega_eng: float
    cdan: float = 0.0       # puffer nozzle discharge area Cd*An [m^2]

    def __post_init__(self):
        c, s = self.c, self.s
        self.rod = s.get("rod_elasticity", 0.0) > 0
        self.gas = s.get("puffer_gas", 0.0) > 0
        if self.rod:
            self.Jr0, self.Je, self.K, self.C = fx.rod_params(c["J2"], s["rod_elasticity"], self.sh["rod_elasticity"])
        else:
            self.Jr0, self.Je, self.K, self.C = c["J2"], 0.0, 0.0, 0.0
        self.n = 2 + (2 if self.rod else 0) + (1 if self.gas else 0)
        self.i_rod, self.i_gas = 2, 2 + (2 if self.rod else 0)
        self.cv = fx.viscous_coeff(c["TOf"], s.get("viscous_friction", 0.0),
                                   self.sh.get("viscous_friction")) if s.get("viscous_friction") else 0.0
        self.ramp = (s.get("latch_ramp", 0.0) * self.sh["latch_ramp"]["ramp_ms"] * 1e-3
                     if s.get("latch_ramp") else 0.0)
        if self.gas:
            self.V0 = PUFFER_AREA * c["raec"] / self.sh["puffer_gas"]["volume_per_rad"]

    def y0(self) -> np.ndarray:
        return np.zeros(self.n)

    # -- torques ---------------------------------------------------------------
    def spring(self, th, t):
        c = self.c
        sh = self.sh.get("spring_nonlinearity", {})
        F = fx.spring_force(c["kO"], c["xO1"] - th * c["rO"], c["xO0"], c["xO1"],
                            self.s.get("spring_nonlinearity", 0.0), sh.get("gamma_opening", 0.0), sh.get("width", 1.0))
        r = 1.0 if self.ramp == 0.0 else min(1.0, max(t, 0.0) / self.ramp)
        return F * c["rO"] * r

    def friction(self, th, w):
        c, s = self.c, self.s.get("stribeck_friction", 0.0)
        T = c["TOf"]
        if s > 0:
            sh = self.sh["stribeck_friction"]
            load = (c["xO1"] - th * c["rO"]) / (0.5 * (c["xO0"] + c["xO1"]))
            g = fx.stribeck_factor(w, load, s, sh) - (1.0 - s * sh["load_share"])
            T = c["TOf"] * (1.0 - s * sh["load_share"]) + c["TOf"] * g * math.tanh(w / EPS_W)
        return T + self.cv * w

    def buffer(self, th, w):
        c = self.c
        d = fx.buffer_damping_torque(w, c["cb"] * c["rb"] ** 2, self.s.get("orifice_buffer", 0.0),
                                     self.sh.get("orifice_buffer"), self.omega_eng)
        return c["kb"] * c["rb"] ** 2 * (th - c["alpha0"]) + d

    def puffer(self, v, dp):
        lin = self.c["caec"] * self.c["raec"] ** 2 * v
        s = self.s.get("puffer_gas", 0.0)
        if s == 0.0:
            return lin
        m = s * self.sh["puffer_gas"]["gas_share"]
        return (1.0 - m) * lin + m * self.puffer_scale * PUFFER_AREA * self.c["raec"] * dp

    def gas_rate(self, thc, v, dp):
        """d(dp)/dt [Pa/s]: polytropic compression by the piston minus the nozzle outflow."""
        n = self.sh["puffer_gas"]["polytropic_n"]
        p = P_FILL + dp
        vol = self.V0 - PUFFER_AREA * self.c["raec"] * thc
        rho = RHO_FILL * (max(p, 1e4) / P_FILL) ** (1.0 / n)
        q = self.cdan * dp * math.sqrt(2.0 / (rho * (abs(dp) + P_EPS)))
        return n * p / vol * (PUFFER_AREA * self.c["raec"] * v - q)

    # -- right-hand side ---------------------------------------------------------
    def rhs(self, t, y, engaged=None):
        th, w = y[0], y[1]
        if engaged is None:
            engaged = th > self.c["alpha0"]
        lam, dlam = fx.linkage_inertia(th, self.s.get("linkage_kinematics", 0.0), self.sh.get("linkage_kinematics"))
        Jr = self.Jr0 * lam
        T = self.spring(th, t) - self.friction(th, w) - 0.5 * self.Jr0 * dlam * w * w
        if engaged:
            T -= self.buffer(th, w)
        dy = np.empty(self.n)
        dp = y[self.i_gas] if self.gas else 0.0
        if self.rod:
            ph, ps = y[2], y[3]
            Trod = self.K * (ph - th) + self.C * (ps - w)
            Tp = self.puffer(ps, dp)
            dy[2], dy[3] = ps, (-Trod - Tp) / self.Je
            T += Trod
            thc, vc = ph, ps
        else:
            T -= self.puffer(w, dp)
            thc, vc = th, w
        acc = T / Jr
        if th <= 0.0 and w <= 0.0 and acc < 0.0:    # held on the closed stop / latch
            acc = 0.0
        dy[0], dy[1] = w, acc
        if self.gas:
            dy[self.i_gas] = self.gas_rate(thc, vc, dp)
        return dy


def build(c: dict, s: dict, shapes: dict, puffer_scale: float = 1.0) -> OpeningModel:
    """The opening model of applied constants ``c``, strengths ``s`` and the unit's shapes."""
    nom = nominal()
    m = OpeningModel(c=c, s=s, sh=shapes, puffer_scale=puffer_scale, omega_eng=nom["omega_eng"])
    if m.gas:
        m.cdan = puffer_nozzle(shapes["puffer_gas"]["volume_per_rad"], shapes["puffer_gas"]["polytropic_n"],
                               shapes["puffer_gas"]["energy_ratio"])
    return m


def integrate(model: OpeningModel, after_peak: float, *, method: str = "DOP853", rtol=RTOL, atol=ATOL):
    """Integrate from release to ``after_peak`` s past the travel peak.

    Returns (segments, events): dense solutions in order and {"engage": t, "peak": t} [s from release].
    The buffer switch is handled by stopping at every alpha0 crossing and restarting.
    """
    a0 = model.c["alpha0"]

    def cross(t, y, *_):
        return y[0] - a0
    cross.terminal = True

    def peak(t, y, *_):   # end of stroke: the shaft has (nearly) stopped beyond 0.9 rad
        return y[1] - PEAK_SPEED + 100.0 * max(0.0, 0.9 - y[0])
    peak.terminal, peak.direction = True, -1

    t, y, segs, events = 0.0, model.y0(), [], {}
    t_end, phase = HORIZON, "rise"
    while t < t_end - 1e-12:
        engaged = y[0] > a0 or (y[0] == a0 and y[1] > 0)
        evs = [cross] + ([peak] if phase == "rise" else [])
        sol = solve_ivp(model.rhs, (t, t_end), y, method=method, rtol=rtol, atol=atol, dense_output=True,
                        events=evs, args=(engaged,), max_step=2e-4)
        if sol.status < 0:
            raise RuntimeError(f"opening integration failed: {sol.message}")
        segs.append(sol)
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if sol.status == 1:
            if sol.t_events[0].size and math.isclose(sol.t_events[0][-1], t, abs_tol=1e-12):
                events.setdefault("engage", t)
                y[0] = a0 + (1e-12 if not engaged else -1e-12)
            elif phase == "rise":
                events["slow"], phase, t_end = t, "fall", t + after_peak + PEAK_SEARCH
    if "slow" not in events:
        raise RuntimeError("the opening did not reach its end of stroke within the horizon")
    # the peak: where the speed crosses 0 shortly after it fell below PEAK_SPEED, else the creep start
    grid = events["slow"] + np.arange(0.0, PEAK_SEARCH, 1e-7)
    w = sample(segs, grid, 1)
    stop = np.nonzero(w <= 0.0)[0]
    events["peak"] = float(grid[stop[0]]) if stop.size else float(events["slow"])
    return segs, events


def sample(segs, times: np.ndarray, index: int = 0) -> np.ndarray:
    """State component ``index`` of the piecewise dense solution at ``times`` [s from release]."""
    out = np.zeros(times.size)
    for sol in segs:
        m = (times >= sol.t[0]) & (times <= sol.t[-1])
        if m.any():
            out[m] = sol.sol(times[m])[index]
    return out


@lru_cache(maxsize=1)
def nominal() -> dict:
    """The design breaker's reduced-model opening: engagement speed [rad/s] and a dense trajectory."""
    m = OpeningModel(c=_design_applied(), s={}, sh={}, puffer_scale=1.0, omega_eng=1.0)
    segs, ev = integrate(m, 0.0)
    t = np.linspace(0.0, ev["peak"], 4001)
    th, w = sample(segs, t, 0), sample(segs, t, 1)
    return {"omega_eng": float(sample(segs, np.array([ev["engage"]]), 1)[0]), "t": t, "theta": th, "omega": w}


def _design_applied() -> dict:
    c = dict(DESIGN)
    c["xO0"] = c["xO1"] - c["rO"]
    return c


@lru_cache(maxsize=256)
def puffer_nozzle(volume_per_rad: float, n: float, energy_ratio: float) -> float:
    """Nozzle area Cd*An [m^2] that makes the gas puffer dissipate ``energy_ratio`` x the linear one.

    Energies are taken along the design breaker's reduced opening (peak), so the gas model only
    reshapes the puffer resistance: its total work is set by a unit-fixed ratio.
    """
    nom, c = nominal(), _design_applied()
    t, th, w = nom["t"], nom["theta"], nom["omega"]
    e_lin = np.trapezoid(c["caec"] * c["raec"] ** 2 * w * w, t)
    arm = PUFFER_AREA * c["raec"]
    v0 = arm / volume_per_rad

    def work(cdan):
        def rate(tt, y):
            thc, v = np.interp(tt, t, th), np.interp(tt, t, w)
            p = P_FILL + y[0]
            rho = RHO_FILL * (max(p, 1e4) / P_FILL) ** (1.0 / n)
            q = cdan * y[0] * math.sqrt(2.0 / (rho * (abs(y[0]) + P_EPS)))
            return [n * p / (v0 - arm * thc) * (arm * v - q)]
        sol = solve_ivp(rate, (0.0, t[-1]), [0.0], t_eval=t, rtol=1e-8, atol=1e-3, max_step=5e-4)
        return np.trapezoid(arm * sol.y[0] * w, t)

    target = energy_ratio * e_lin
    return math.exp(brentq(lambda la: work(math.exp(la)) - target, math.log(1e-7), math.log(5e-2), xtol=1e-4))
