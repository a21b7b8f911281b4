"""Simulating the virtual prototype: one opening or closing with chosen effects.

Two integrators share ``dynamics``'s right-hand sides:

- ``method="exact"``: scipy ``solve_ivp`` (DOP853, rtol 1e-9), restarted at every switch of the
  equations (buffer engagement α0, contact touch, end of the cam rise) so no step straddles a
  discontinuity. This is the reference.
- ``method="fast"``: compiled fixed-step RK4 (steps ≤ 1/128 kHz landing on every sample), for
  the diagnosis fits that run it thousands of times; validated against ``exact`` in the tests.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.integrate import solve_ivp

from service.mechanics.breaker import Breaker
from service.mechanics.trajectory import Trajectory
from service.mechanics.effects import dynamics
from service.mechanics.effects.integrator import closing_constants, integrate, opening_constants
from service.mechanics.effects.sensor_nonlinearity import sensor_reading
from .effects import EFFECT_NAMES, Effects, check_operation, effect_vector

OPENING_PARAMETERS = ("AO", "BO", "DO", "EO")
CLOSING_PARAMETERS = ("AC", "BC", "CC", "DC")
FAST_DT = 1.0 / 128_000  # [s]


def _param_vector(params: Mapping[str, float], names) -> np.ndarray:
    missing = [k for k in names if k not in params]
    if missing:
        raise ValueError(f"missing model parameter(s) {', '.join(missing)}")
    return np.array([float(params[k]) for k in names])


def _failed(t, msg):
    nan = np.full_like(t, np.nan)
    return Trajectory(t, nan, nan, False, msg, np.nan)


def simulate_prototype_opening(params: Mapping[str, float], t, *, breaker: Breaker,
                               effects: Effects = Effects(), method: str = "exact",
                               dt_max: float = FAST_DT) -> Trajectory:
    """One opening of the virtual prototype on times ``t`` [s since motion start].

    Parameters
    ----------
    params : mapping
        AO [s^-2], BO [s^-2], DO [s^-1], EO [s^-2] (CO and α0 come from ``breaker``).
    t : array_like
        Evaluation times [s], non-decreasing; negative times give the rest state.
    breaker : Breaker
    effects : Effects
        Strengths of the effects (all off: Eq. 11 exactly).
    method : {"exact", "fast"}
    dt_max : float
        Largest RK4 step of the ``fast`` method [s].

    Returns
    -------
    Trajectory
        ``theta`` is the travel the sensor reads [rad from closed]; events ``buffer_engaged`` [s].
    """
    check_operation(effects, "open")
    p = _param_vector(params, OPENING_PARAMETERS)
    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(p)) or p[0] <= 0:
        return _failed(t, f"invalid opening parameters {dict(zip(OPENING_PARAMETERS, p))}")
    c = opening_constants(breaker)
    e = effect_vector(effects.as_array())
    x0 = np.zeros(4)
    if method == "fast":
        theta, omega, ev = integrate(0, x0, p, e, c, None, t, dt_max)
        t_buf, t_peak = ev[0], ev[1]
    elif method == "exact":
        theta, omega, t_buf, t_peak, _ = _exact_opening(x0, p, e, c, t)
    else:
        raise ValueError(f"method must be 'exact' or 'fast', got {method!r}")
    theta = sensor_reading(theta, effects.sensor_nonlinearity, breaker.stroke)
    engaged = bool(np.isfinite(t_buf))
    msg = "ok" if engaged else "the opening never reached the buffer (θ stayed below α0)"
    return Trajectory(t, theta, omega, engaged, msg, float(t_peak),
                      {"buffer_engaged": float(t_buf)})


def simulate_prototype_closing(params: Mapping[str, float], t, *, breaker: Breaker,
                               effects: Effects = Effects(), method: str = "exact",
                               dt_max: float = FAST_DT) -> Trajectory:
    """One closing of the virtual prototype on times ``t`` [s since latch release].

    Parameters
    ----------
    params : mapping
        AC [s^-2], BC [-], CC [s^-2], DC [s^-2].
    t : array_like
        Evaluation times [s], non-decreasing.
    breaker : Breaker
    effects : Effects
        Strengths (all off: Eq. 7 exactly).
    method : {"exact", "fast"}
    dt_max : float
        Largest RK4 step of the ``fast`` method [s].

    Returns
    -------
    Trajectory
        ``theta`` is θ2 in the closing coordinate (0 = open) as the sensor reads it; events
        ``contact_touch`` [s].
    """
    check_operation(effects, "close")
    p = _param_vector(params, CLOSING_PARAMETERS)
    t = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(p)) or p[1] <= 0:
        return _failed(t, f"invalid closing parameters {dict(zip(CLOSING_PARAMETERS, p))}")
    c = closing_constants(breaker)
    e = effect_vector(effects.as_array())
    h0 = float(breaker.cam.theta2[0])
    x0 = np.array([c[3], 0.0, h0, 0.0])
    if method == "fast":
        theta, omega, ev = integrate(1, x0, p, e, c, breaker.cam, t, dt_max)
        t_touch, t_peak, stalled = ev[0], ev[1], bool(ev[2])
    elif method == "exact":
        theta, omega, t_touch, t_peak, stalled, _ = _exact_closing(x0, p, e, c, breaker.cam, t)
    else:
        raise ValueError(f"method must be 'exact' or 'fast', got {method!r}")
    if effects.sensor_nonlinearity:
        travel = sensor_reading(breaker.stroke - theta, effects.sensor_nonlinearity, breaker.stroke)
        theta = breaker.stroke - travel
    if stalled:
        msg = "the camshaft stalled before the contacts closed (closing spring too weak for the load)"
    elif not np.isfinite(t_peak):
        msg = "the closing did not reach the end of the cam rise within the simulated time"
    else:
        msg = "ok"
    return Trajectory(t, theta, omega, not stalled, msg, float(t_peak),
                      {"contact_touch": float(t_touch)})


def prototype_state(operation: str, params: Mapping[str, float], t, *, breaker: Breaker,
                     effects: Effects = Effects()) -> np.ndarray:
    """Full state of the exact integration at ``t`` [s], shape (4, m), for energy audits.

    Opening rows: θ [rad], θ' [rad/s], φ [rad], φ' [rad/s]; closing rows: θ1, θ1', φ, φ'
    (φ: contact-side angle referred to the output shaft; equal to the shaft angle for a rigid rod).
    The sensor nonlinearity is not applied (this is the mechanism, not the reading).
    """
    check_operation(effects, operation)
    t = np.asarray(t, dtype=float)
    e = effect_vector(effects.as_array())
    if operation == "open":
        p = _param_vector(params, OPENING_PARAMETERS)
        return _exact_opening(np.zeros(4), p, e, opening_constants(breaker), t)[-1]
    p = _param_vector(params, CLOSING_PARAMETERS)
    c = closing_constants(breaker)
    x0 = np.array([c[3], 0.0, float(breaker.cam.theta2[0]), 0.0])
    return _exact_closing(x0, p, e, c, breaker.cam, t)[-1]


def _piecewise(rhs, x0, t_end, switches, t_eval):
    """Integrate from 0 to ``t_end``, restarting at each terminal switch event.

    Returns the solution at ``t_eval`` (dense output), and the event times per switch [s].
    """
    times = {}
    segments = []
    t0, x = 0.0, np.asarray(x0, float)
    remaining = list(switches)
    while t0 < t_end:
        evs = [s[1] for s in remaining]
        for ev in evs:
            ev.terminal = True
        sol = solve_ivp(rhs, (t0, t_end), x, method="DOP853", rtol=1e-9, atol=1e-11,
                        dense_output=True, events=evs or None)
        if not sol.success:
            raise RuntimeError(sol.message)
        segments.append((t0, sol.t[-1], sol.sol))
        hit = None
        for (name, _ev), te in zip(remaining, sol.t_events or []):
            if len(te):
                hit = name
                times[name] = float(te[0])
        if hit is None or sol.t[-1] >= t_end:
            break
        remaining = [s for s in remaining if s[0] != hit]
        t0, x = sol.t[-1], sol.y[:, -1]
    out = np.empty((len(x0), t_eval.size))
    for a, b, f in segments:
        sel = (t_eval >= a) & (t_eval <= b)
        if np.any(sel):
            out[:, sel] = f(t_eval[sel])
    last = segments[-1]
    out[:, t_eval > last[1]] = last[2](last[1])[:, None]
    return out, times


def _exact_opening(x0, p, e, c, t):
    def rhs(_t, x):
        return dynamics.opening_rhs(x, p, e, c)

    alpha0 = c[1]

    def at_buffer(_t, x):
        return x[0] - alpha0
    at_buffer.direction = 1

    tc = np.maximum(t, 0.0)
    t_end = max(float(tc.max()) if tc.size else 0.0, 0.2)
    y, times = _piecewise(rhs, x0, t_end, [("buffer", at_buffer)], tc)
    t_buf = times.get("buffer", np.nan)
    t_peak = np.nan
    if np.isfinite(t_buf):
        # First velocity zero after engagement: the end of the valid interval.
        sol = solve_ivp(rhs, (t_buf, t_end), _state_at(rhs, x0, t_buf, alpha0), method="DOP853",
                        rtol=1e-9, atol=1e-11, events=_speed_zero)
        if len(sol.t_events[0]):
            t_peak = float(sol.t_events[0][0])
    return y[0], y[1], t_buf, t_peak, y


def _speed_zero(_t, x):
    return x[1]


_speed_zero.direction = -1


def _state_at(rhs, x0, t1, alpha0):
    sol = solve_ivp(rhs, (0.0, t1), x0, method="DOP853", rtol=1e-9, atol=1e-11)
    x = sol.y[:, -1].copy()
    x[0] = max(x[0], alpha0)
    return x


def _exact_closing(x0, p, e, c, cam, t):
    cx, cy, cc = cam.theta1, cam.theta2, cam.coefficients

    def rhs(_t, x):
        return dynamics.closing_rhs(x, p, e, c, cx, cy, cc)

    touch, rise_end = c[6], c[9]

    def at_touch(_t, x):
        return x[2] - touch
    at_touch.direction = 1

    def at_rise_end(_t, x):
        return x[0] - rise_end
    at_rise_end.direction = 1

    def at_stall(_t, x):
        return x[1] if _t > 0 else 1.0
    at_stall.direction = -1

    def at_knot(k):
        def f(_t, x):
            return x[0] - cam.theta1[k]
        f.direction = 1
        return f

    tc = np.maximum(t, 0.0)
    t_end = max(float(tc.max()) if tc.size else 0.0, 0.2)
    # The cam spline's h'' jumps at its knots only in the third derivative, so no restart there;
    # the switches are the contact touch, the end of the rise and a stall.
    y, times = _piecewise(rhs, x0, t_end, [("touch", at_touch), ("rise_end", at_rise_end),
                                            ("stall", at_stall)], tc)
    stalled = "stall" in times and times["stall"] < times.get("rise_end", np.inf)
    h, h1, _ = cam.evaluate(y[0])
    return h, h1 * y[1], times.get("touch", np.nan), times.get("rise_end", np.nan), stalled, y
