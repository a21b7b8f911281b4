"""The compiled integrator of the reduced models plus any set of catalogued effects.

``simulate_effects`` is the public entry: one opening or closing at given times with a list of
(effect, strength, shape). It runs ``dynamics.integrate_rk4`` (fixed-step RK4 landing on every
requested time, compiled), fast enough for the thousands of evaluations of a fit.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from ..breaker import Breaker
from . import dynamics
from .catalogue import EFFECT_NAMES, N_SHAPES, effect_vector
from .contact_wipe import TOUCH_FRACTION
from .sensor_nonlinearity import sensor_reading

_EMPTY = np.zeros(2)
_EMPTY2 = np.zeros((4, 1))
OPENING_STATE = ("AO", "BO", "DO", "EO")
CLOSING_STATE = ("AC", "BC", "CC", "DC")

# A cheap tally of the compiled integrations (their count, trajectories and seconds inside the
# kernel, summed over threads): what a diagnosis spends is measured, not guessed
# (bench/diagnose_speed.py reads it per stage). A lock per call costs ~0.1 µs against ~1 ms.
_TALLY_LOCK = threading.Lock()
_TALLY = {"calls": 0, "trajectories": 0, "seconds": 0.0, "coarse": 0}
_FINE_DT = 1.0 / 16_000   # the curves' step: a call with a larger one counts as ``coarse``


def tally() -> dict:
    """A copy of the running tally: ``calls`` (kernel calls), ``trajectories`` (state
    trajectories integrated), ``coarse`` (those on a grid coarser than the curves' 1/16000 s:
    a Jacobian's columns, ~2.4x cheaper each) and ``seconds`` (inside the kernel, summed over
    threads) since the process started."""
    with _TALLY_LOCK:
        return dict(_TALLY)


def _count(trajectories: int, seconds: float, coarse: bool = False) -> None:
    with _TALLY_LOCK:
        _TALLY["calls"] += 1
        _TALLY["trajectories"] += trajectories
        _TALLY["seconds"] += seconds
        _TALLY["coarse"] += trajectories if coarse else 0


def opening_constants(breaker: Breaker, *, CO: float | None = None, alpha0: float | None = None) -> np.ndarray:
    """[CO s^-1, α0 rad, X1 = xO1/rO rad, stroke rad] for ``dynamics.opening_rhs``; ``CO`` and
    ``alpha0`` override the breaker's (a capture's own damping, a unit's own buffer angle)."""
    return np.array([breaker.CO if CO is None else CO, breaker.alpha0 if alpha0 is None else alpha0,
                     breaker.xO1 / breaker.rO, breaker.stroke])


def closing_constants(breaker: Breaker, *, CO: float | None = None) -> np.ndarray:
    """Constants for ``dynamics.closing_rhs`` (see its module for the layout); ``CO`` overrides
    the breaker's damping [s^-1]."""
    g = breaker.closing_geometry
    cam = breaker.cam
    h0, h_end = float(cam.theta2[0]), float(cam.theta2.max())
    th = g.theta1_start
    g_start = (g.xC0 - g.rC * (1 - np.cos(th))) * np.sin(th) / (g.d + g.rC * np.cos(th))
    touch = h0 + TOUCH_FRACTION * (h_end - h0)
    return np.array([g.xC0, g.rC, g.d, th, breaker.CO if CO is None else CO, g_start, touch, h_end,
                     0.5 * (h0 + h_end), cam.rise_end])


def integrate(op: int, x0, p, e, c, cam, t, dt_max: float):
    """(θ, ω, events) at times ``t`` [s, clipped at 0, non-decreasing] by compiled RK4.

    op 0 opening / 1 closing; x0 the initial state; p the reduced parameters; e the effect
    vector (``effect_vector``); c the constants (``opening_constants`` / ``closing_constants``);
    cam the closing's cam profile (None for an opening); dt_max the largest step [s]."""
    tc = np.maximum(t, 0.0)
    if tc.size and np.any(np.diff(tc) < 0):
        raise ValueError("the integrator needs non-decreasing times")
    if cam is None:
        cx, cy, cc = _EMPTY, _EMPTY, _EMPTY2
    else:
        cx, cy, cc = cam.theta1, cam.theta2, cam.coefficients
    t0 = time.perf_counter()
    out = dynamics.integrate_rk4(op, x0, p, e, c, cx, cy, cc, np.ascontiguousarray(tc), float(dt_max))
    _count(1, time.perf_counter() - t0, dt_max > _FINE_DT * (1 + 1e-9))
    return out


def simulate_effects(operation: str, params: dict, t, breaker: Breaker, effects=(), *,
                     dt_max: float = 1.0 / 16_000, sensor_side: bool = False,
                     CO: float | None = None, alpha0: float | None = None):
    """Operation coordinate [rad] at ``t`` [s since motion onset, ≥ 0] with any set of effects.

    ``params``: AO, BO, DO, EO [s^-2, s^-2, s^-1, s^-2] (opening) or AC, BC, CC, DC (closing);
    ``effects``: sequence of (name, strength, shape or None); ``sensor_side`` True reads a
    contact-side sensor (the rod's contact mass) for ``rod_elasticity``; ``CO`` [s^-1] and
    ``alpha0`` [rad] override the breaker's. Returns (theta, ok).
    """
    names = OPENING_STATE if operation == "open" else CLOSING_STATE
    p = np.array([float(params[k]) for k in names])
    strengths = np.zeros(len(EFFECT_NAMES))
    shapes = {}
    for name, s, sh in effects:
        strengths[EFFECT_NAMES.index(name)] = s
        if sh is not None:
            shapes[name] = np.array(sh, float)
    if sensor_side and "rod_elasticity" in shapes:
        shapes["rod_elasticity"] = shapes["rod_elasticity"].copy()
        shapes["rod_elasticity"][1] = 1.0
    e = effect_vector(strengths, shapes or None)
    if not np.all(np.isfinite(p)) or p[0 if operation == "open" else 1] <= 0:
        return np.full_like(t, np.nan), False
    if operation == "open":
        theta, _, _ = integrate(0, np.zeros(4), p, e, opening_constants(breaker, CO=CO, alpha0=alpha0),
                                None, t, dt_max)
    else:
        c = closing_constants(breaker, CO=CO)
        x0 = np.array([c[3], 0.0, float(breaker.cam.theta2[0]), 0.0])
        theta, _, _ = integrate(1, x0, p, e, c, breaker.cam, t, dt_max)
    for name, s, sh in effects:
        if name == "sensor_nonlinearity" and s != 0.0:
            k = len(EFFECT_NAMES) + N_SHAPES * EFFECT_NAMES.index(name)
            pw, g = e[k], e[k + 1]
            if operation == "open":
                theta = sensor_reading(theta, s, breaker.stroke, pw, g)
            else:
                theta = breaker.stroke - sensor_reading(breaker.stroke - theta, s, breaker.stroke, pw, g)
    return theta, bool(np.all(np.isfinite(theta)))
