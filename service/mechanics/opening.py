"""Opening model (Yan et al. 2026, Eq. 11): output shaft driven by the opening spring,
with the hydraulic buffer engaged past α0.

    θ'' = -AO·θ + BO - CO·θ'                              θ <= α0
    θ'' = -AO·θ + BO - CO·θ' - DO·θ' - EO·(θ - α0)        θ >  α0

θ is the output-shaft angle from the closed position [rad]; θ(0) = 0, θ'(0) = 0.
Each segment is linear with constant coefficients and is solved in closed form; the switch time
is the exact α0 crossing. No step size is involved.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .damped_response import damped_response, first_peak_time
from .trajectory import Trajectory

PARAMETERS = ("AO", "BO", "DO", "EO")


def opening_rhs(t, x, params: Mapping[str, float], CO: float, alpha0: float):
    """Right-hand side of Eq. 11 for an ODE solver, ``f(t, x, params)``.

    Parameters
    ----------
    t : float
        Time [s] (unused: the model is autonomous).
    x : sequence
        State [θ rad, θ' rad/s].
    params : mapping
        AO [s^-2], BO [s^-2], DO [s^-1], EO [s^-2].
    CO : float
        Puffer damping factor [s^-1].
    alpha0 : float
        Buffer engagement angle [rad].
    """
    theta, omega = x[0], x[1]
    acc = -params["AO"] * theta + params["BO"] - CO * omega
    if theta > alpha0:
        acc -= params["DO"] * omega + params["EO"] * (theta - alpha0)
    return [omega, acc]


def buffer_engagement_time(AO, BO, CO, alpha0, t_max):
    """Exact time at which the opening angle first reaches α0 [s]; NaN where it never does.

    Arguments broadcast, so a population of parameter sets is one call.
    """
    AO, BO = np.broadcast_arrays(np.asarray(AO, float), np.asarray(BO, float))
    CO = np.broadcast_to(np.asarray(CO, float), AO.shape)
    t_hi = np.broadcast_to(first_peak_time(AO, CO, t_max), AO.shape).astype(float)
    # The pre-buffer segment rises monotonically until its first peak, so the crossing is
    # bracketed on [0, t_hi]; bisection then Newton gives machine precision.
    x_hi, _ = damped_response(t_hi, AO, CO, BO, 0.0, 0.0)
    crosses = x_hi >= alpha0
    lo = np.zeros_like(t_hi)
    hi = t_hi.copy()
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        x_mid, _ = damped_response(mid, AO, CO, BO, 0.0, 0.0)
        above = x_mid >= alpha0
        hi = np.where(above, mid, hi)
        lo = np.where(above, lo, mid)
    ts = 0.5 * (lo + hi)
    for _ in range(3):
        x_s, v_s = damped_response(ts, AO, CO, BO, 0.0, 0.0)
        step = np.where(v_s > 0, (x_s - alpha0) / np.where(v_s > 0, v_s, 1.0), 0.0)
        ts = np.clip(ts - step, lo, hi)
    return np.where(crosses, ts, np.nan)


def opening_angle(t, AO, BO, DO, EO, *, CO: float, alpha0: float):
    """Opening angle and speed at times ``t`` since motion start.

    Parameters
    ----------
    t : array_like, shape (m,)
        Time since the start of motion [s]; negative times give the rest state.
    AO, BO, DO, EO : array_like
        Model parameters [s^-2, s^-2, s^-1, s^-2]; give them shape (n, 1) to evaluate a
        population of n parameter sets at once.
    CO : float
        Puffer damping factor [s^-1] (structural, not estimated).
    alpha0 : float
        Buffer engagement angle [rad] (structural).

    Returns
    -------
    theta, omega : ndarray, broadcast shape of ``t`` and the parameters
        Angle from the closed position [rad] and angular speed [rad/s].
    ts : ndarray
        Buffer engagement time [s] (NaN if the buffer is never reached).
    """
    t = np.asarray(t, dtype=float)
    AO, BO, DO, EO = (np.asarray(p, dtype=float) for p in (AO, BO, DO, EO))
    t_max = float(np.max(t)) if t.size else 0.0
    ts = buffer_engagement_time(AO, BO, CO, alpha0, max(t_max, 1e-9))
    tc = np.maximum(t, 0.0)
    x1, v1 = damped_response(tc, AO, CO, BO, 0.0, 0.0)
    engaged = np.isfinite(ts)
    ts_safe = np.where(engaged, ts, np.inf)
    _, vs = damped_response(np.where(engaged, ts, 0.0), AO, CO, BO, 0.0, 0.0)
    a2 = AO + EO
    f2 = BO + EO * alpha0
    tau = np.maximum(tc - np.where(engaged, ts, 0.0), 0.0)
    x2, v2 = damped_response(tau, a2, CO + DO, f2, alpha0, vs)
    after = tc > ts_safe
    theta = np.where(after, x2, x1)
    omega = np.where(after, v2, v1)
    at_rest = t < 0
    theta = np.where(at_rest, 0.0, theta)
    omega = np.where(at_rest, 0.0, omega)
    return theta, omega, ts


def opening_peak_time(AO, BO, DO, EO, *, CO: float, alpha0: float, t_max: float = 0.5):
    """Time of the maximum opening angle, the end of the valid interval [s].

    It is the first velocity zero after buffer engagement (or of the pre-buffer segment when
    the buffer is never reached).
    """
    AO, BO, DO, EO = (np.asarray(p, dtype=float) for p in (AO, BO, DO, EO))
    ts = buffer_engagement_time(AO, BO, CO, alpha0, t_max)
    engaged = np.isfinite(ts)
    _, vs = damped_response(np.where(engaged, ts, 0.0), AO, CO, BO, 0.0, 0.0)
    a2, c2 = AO + EO, CO + DO
    f2 = BO + EO * alpha0
    # Velocity of segment 2 vanishes at a closed-form instant when under-damped.
    sigma = 0.5 * c2
    omega2 = a2 - sigma**2
    x_eq = f2 / a2
    c1 = alpha0 - x_eq
    cc2 = vs + sigma * c1
    A = cc2 - sigma * c1
    B = -(sigma * cc2 + omega2 * c1)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.sqrt(np.where(omega2 > 0, omega2, np.nan))
        # v ∝ A cos(wτ) + (B/w) sin(wτ) = 0  ->  tan(wτ) = -A w / B
        tau = np.arctan2(-A * w, B) / w
        tau = np.where(tau <= 0, tau + np.pi / w, tau)
    t_peak_buffer = ts + tau
    t_peak_free = first_peak_time(AO, CO, t_max)
    return np.where(engaged, t_peak_buffer, t_peak_free)


def simulate_opening(params: Mapping[str, float], t, *, CO: float, alpha0: float) -> Trajectory:
    """Simulate one opening on times ``t`` [s since motion start].

    Parameters
    ----------
    params : mapping
        AO [s^-2], BO [s^-2], DO [s^-1], EO [s^-2].
    t : array_like
        Evaluation times [s].
    CO : float
        Puffer damping factor [s^-1].
    alpha0 : float
        Buffer engagement angle [rad].
    """
    p = [float(params[k]) for k in PARAMETERS]
    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(p)) or p[0] <= 0:
        return Trajectory(t, np.full_like(t, np.nan), np.full_like(t, np.nan), False,
                          f"invalid opening parameters {dict(zip(PARAMETERS, p))}", np.nan)
    theta, omega, ts = opening_angle(t, *p, CO=CO, alpha0=alpha0)
    t_peak = float(opening_peak_time(*p, CO=CO, alpha0=alpha0, t_max=max(float(t.max()), 0.5)))
    engaged = bool(np.isfinite(ts))
    msg = "ok" if engaged else "the opening never reached the buffer (θ stayed below α0)"
    return Trajectory(t, theta, omega, engaged, msg, t_peak,
                      {"buffer_engaged": float(ts) if engaged else float("nan")})
