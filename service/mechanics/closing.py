"""Closing model (Yan et al. 2026, Eqs. 2-7): the closing spring drives the camshaft, the cam
drives the output shaft against the opening spring.

With the cam contact torque eliminated (T21 = T12·h', θ2'' = h'·θ1'' + h''·θ1'²):

    θ1''·(1 + BC·h'²) = AC·g(θ1) - BC·h'·(h''·θ1'² + CC + DC·h(θ1))
    g(θ1) = [xC0 - rC·(1 - cos θ1)]·sin θ1 / (d + rC·cos θ1)

θ1 is the camshaft angle [rad], θ2 = h(θ1) the output-shaft angle in the closing coordinate
(0 = open). Motion starts at θ1 = θ1_start with θ1' = 0; the valid interval ends at the maximum
of θ2. AC [s^-2], BC [-], CC [s^-2], DC [s^-2] (DC = AO from the opening fit).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .cam_profile import CamProfile
from .closing_kernel import integrate_closing_batch
from .trajectory import Trajectory

PARAMETERS = ("AC", "BC", "CC")


@dataclass(frozen=True)
class ClosingGeometry:
    """Structural constants of the closing spring–camshaft system.

    Attributes
    ----------
    xC0 : float
        Closing-spring compression after charging [m].
    rC : float
        Crank radius driven by the closing spring [m].
    d : float
        Camshaft axis to closing-spring axis [m].
    theta1_start : float
        Camshaft angle at closing-latch release [rad], past dead centre.
    """

    xC0: float
    rC: float
    d: float
    theta1_start: float


def closing_spring_lever(theta1, geometry: ClosingGeometry):
    """g(θ1) of Eq. 2 [m]: the closing spring's torque per unit (kC·rC·d) at camshaft angle θ1 [rad]."""
    theta1 = np.asarray(theta1, dtype=float)
    g = geometry
    return (g.xC0 - g.rC * (1.0 - np.cos(theta1))) * np.sin(theta1) / (g.d + g.rC * np.cos(theta1))


def closing_rhs(t, x, params: Mapping[str, float], cam: CamProfile, geometry: ClosingGeometry):
    """Right-hand side of Eq. 7 for an ODE solver; state [θ1 rad, θ1' rad/s]."""
    theta1, omega1 = x[0], x[1]
    h, h1, h2 = (float(v) for v in cam.evaluate(theta1))
    BC = params["BC"]
    drive = params["AC"] * float(closing_spring_lever(theta1, geometry))
    load = BC * h1 * (h2 * omega1**2 + params["CC"] + params["DC"] * h)
    return [omega1, (drive - load) / (1.0 + BC * h1 * h1)]


def closing_angle(t, P, *, cam: CamProfile, geometry: ClosingGeometry, dt_max: float = 1 / 64000,
                  tau=None):
    """Output-shaft angle θ2 for a population of closing parameter sets.

    Parameters
    ----------
    t : array_like, shape (m,)
        Non-decreasing times since latch release [s]; negative times give the rest state.
    P : array_like, shape (n, 4)
        Rows of [AC s^-2, BC -, CC s^-2, DC s^-2].
    cam : CamProfile
    geometry : ClosingGeometry
    dt_max : float
        Largest RK4 step [s]; steps also land on every ``t``.
    tau : array_like, shape (n,), optional
        Per-row delay of the latch release [s]: row i is evaluated at ``t - tau[i]``.

    Returns
    -------
    theta2 : ndarray (n, m)
        Closing-coordinate angle [rad].
    omega2 : ndarray (n, m)
        Its speed [rad/s].
    t_peak : ndarray (n,)
        Time θ1 reaches the end of the cam rise (the θ2 maximum) [s]; NaN if never.
    stalled : ndarray (n,) of bool
        The camshaft stopped or turned back before the end of the rise.
    """
    t = np.ascontiguousarray(t, dtype=float)
    P = np.ascontiguousarray(np.atleast_2d(P), dtype=float)
    if t.size and np.any(np.diff(t) < 0):
        raise ValueError("closing_angle needs non-decreasing times")
    tau = np.zeros(P.shape[0]) if tau is None else np.ascontiguousarray(
        np.broadcast_to(np.asarray(tau, dtype=float), (P.shape[0],)))
    g = geometry
    return integrate_closing_batch(
        P, t, tau, float(dt_max), g.xC0, g.rC, g.d, g.theta1_start,
        cam.theta1, cam.theta2, cam.coefficients, cam.rise_end)


def simulate_closing(params: Mapping[str, float], t, *, cam: CamProfile,
                     geometry: ClosingGeometry, dt_max: float = 1 / 64000) -> Trajectory:
    """Simulate one closing on times ``t`` [s since latch release].

    Parameters
    ----------
    params : mapping
        AC [s^-2], BC [-], CC [s^-2], DC [s^-2].
    """
    p = np.array([[float(params[k]) for k in ("AC", "BC", "CC", "DC")]])
    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(p)) or p[0, 1] <= 0:
        return Trajectory(t, np.full_like(t, np.nan), np.full_like(t, np.nan), False,
                          f"invalid closing parameters {params}", np.nan)
    theta2, omega2, t_peak, stalled = closing_angle(t, p, cam=cam, geometry=geometry, dt_max=dt_max)
    ok = not bool(stalled[0])
    if ok and not np.isfinite(t_peak[0]):
        msg = "the closing did not reach the end of the cam rise within the simulated time"
    elif ok:
        msg = "ok"
    else:
        msg = "the camshaft stalled before the contacts closed (closing spring too weak for the load)"
    return Trajectory(t, theta2[0], omega2[0], ok, msg, float(t_peak[0]),
                      {"cam_rise": _rise_time(t, theta2[0], cam)})


def _rise_time(t, theta2, cam: CamProfile) -> float:
    moving = np.nonzero(theta2 > cam.theta2[0] + 1e-6)[0]
    return float(t[moving[0]]) if moving.size else float("nan")
