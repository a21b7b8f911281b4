"""Prototype D's true travel on the sampling grid, and what its transducer makes of it.

``true_travel`` integrates one operation (``dynamics``) with fixed-step RK4 at ``SUBSTEPS``
steps per sample and reads it at the sample times by cubic Hermite interpolation (θ and θ̇
are both integrated, so the read-out is fourth-order like the steps). ``sensor_reading``
applies the transducer: first-order lag, the bow of its characteristic, gain and zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from service.prototypes.d.cam import cam_table
from service.prototypes.d.dynamics import (
    INDEX,
    close_travel,
    integrate_close,
    integrate_open,
)
from service.prototypes.d.effects import SCALES
from service.prototypes.d.unit import design, parameter_vector, physical

SAMPLE_RATE_HZ = 128_000.0
SUBSTEPS = 2  # RK4 at 3.9 µs: the stiffest mode (pin contact, 1.5 kHz) has ω·dt ≈ 0.04


@dataclass(frozen=True)
class Motion:
    """One operation's true motion on the sampling grid.

    Attributes
    ----------
    travel : ndarray
        Output-shaft angle from the closed position [rad].
    rate : ndarray
        Its time derivative [rad/s].
    release_s : float
        Latch release [s from the first sample].
    events_s : dict
        Times [s from the first sample] of the mechanical shocks: ``latch``, and ``buffer``
        and ``end`` (opening) or ``touch`` and ``closed`` (closing), when they happen.
    """

    travel: np.ndarray
    rate: np.ndarray
    release_s: float
    events_s: dict


def _hermite(t_fine, y, dy, t):
    """Cubic Hermite interpolant of (y, dy) on the uniform grid t_fine at times t."""
    dt = t_fine[1] - t_fine[0]
    f = (t - t_fine[0]) / dt
    i = np.clip(np.floor(f).astype(int), 0, len(t_fine) - 2)
    s = f - i
    h00, h10 = (1 + 2 * s) * (1 - s) ** 2, s * (1 - s) ** 2
    h01, h11 = s * s * (3 - 2 * s), s * s * (s - 1)
    val = h00 * y[i] + h10 * dt * dy[i] + h01 * y[i + 1] + h11 * dt * dy[i + 1]
    dval = (6 * s * s - 6 * s) / dt * (y[i] - y[i + 1]) + (1 - 4 * s + 3 * s * s) * dy[i] + (
        3 * s * s - 2 * s) * dy[i + 1]
    return val, dval


def true_travel(operation: str, constants: dict, effects: dict, release_s: float,
                n_samples: int, sample_rate: float = SAMPLE_RATE_HZ) -> Motion:
    """The true travel of ``operation`` for a unit's constants under its conditions
    (``unit.physical``) with ``effects`` {name: strength}, latch released at release_s [s]."""
    P = parameter_vector(operation, constants, effects, v_ref=design_buffer_speed())
    t = np.arange(n_samples) / sample_rate
    dt = 1.0 / (sample_rate * SUBSTEPS)
    n = math.ceil((t[-1] - release_s) / dt) + 1
    t_fine = release_s + dt * np.arange(n + 1)
    if operation == "open":
        states = integrate_open(P, dt, n)
        th_f, w_f = states[:, 0], states[:, 1]
        rest = 0.0
    else:
        table = cam_table()
        states = integrate_close(P, table, constants["theta1_start"], dt, n)
        th_f, w_f = close_travel(states, P, table)
        rest = th_f[0]
    after = t >= release_s
    travel = np.full(n_samples, rest)
    rate = np.zeros(n_samples)
    travel[after], rate[after] = _hermite(t_fine, th_f, w_f, t[after])
    return Motion(travel, rate, release_s, _events(operation, travel, t, release_s, P))


def _events(operation, travel, t, release_s, P) -> dict:
    events = {"latch": release_s}
    if operation == "open":
        past = np.flatnonzero(travel >= P[INDEX["alpha0"]])
        if past.size:
            events["buffer"] = float(t[past[0]])
            events["end"] = float(t[past[0] + int(np.argmax(travel[past[0]:]))])
    else:
        theta2 = P[INDEX["stroke"]] - travel
        touch = np.flatnonzero(theta2 >= SCALES["contact_wipe"]["theta2_touch"])
        if touch.size:
            events["touch"] = float(t[touch[0]])
        closed = np.flatnonzero(theta2 >= theta2.max() - 1e-4)
        if closed.size and theta2.max() > 0.5:
            events["closed"] = float(t[closed[0]])
    return events


@lru_cache(maxsize=1)
def design_buffer_speed() -> float:
    """Buffer piston speed [m/s] at engagement for the design unit at 20 °C, effects off: the
    speed at which the orifice law is matched to the reduced model's linear damping."""
    c = physical(design() | {"spring_sign": 1.0, "sensor_sign": 1.0},
                 {"temperature_C": 20.0, "damping_factor": 1.0})
    P = parameter_vector("open", c, {})
    dt = 1.0 / (SAMPLE_RATE_HZ * SUBSTEPS)
    states = integrate_open(P, dt, int(0.06 / dt))
    k = int(np.argmax(states[:, 0] >= c["alpha0"]))
    return float(c["rb"] * states[k, 1])


def sensor_reading(travel: np.ndarray, unit: dict, effects: dict,
                   sample_rate: float = SAMPLE_RATE_HZ) -> np.ndarray:
    """What the transducer reads [rad] for the true travel [rad]: a first-order lag
    (``sensor_lag``, exact for a travel linear between samples), the bow
    b·4u(1−u), u = θ/1 rad (``sensor_nonlinearity``), then gain and zero."""
    theta = np.asarray(travel, dtype=float)
    tau = float(effects.get("sensor_lag", 0.0)) * SCALES["sensor_lag"]["tau_s"]
    if tau > 0:
        theta = _first_order_lag(theta, tau / (1.0 / sample_rate))
    bow = float(effects.get("sensor_nonlinearity", 0.0)) * SCALES["sensor_nonlinearity"]["bow_rad"]
    if bow:
        theta = theta + unit["sensor_sign"] * bow * 4 * theta * (1 - theta)
    return unit["sensor_offset"] + unit["sensor_gain"] * theta


def _first_order_lag(u: np.ndarray, tau_samples: float) -> np.ndarray:
    """y′ = (u − y)/τ with u linear between samples (τ in samples), starting settled."""
    a = math.exp(-1.0 / tau_samples)
    b1 = 1 - tau_samples * (1 - a)      # weight of u[n] for the ramp part
    b0 = tau_samples * (1 - a) - a      # weight of u[n−1]
    y = np.empty_like(u)
    y[0] = u[0]
    for n in range(1, u.size):
        y[n] = a * y[n - 1] + b1 * u[n] + b0 * u[n - 1]
    return y
