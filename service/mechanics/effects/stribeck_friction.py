"""Breakaway friction above the sliding friction at low speed (``stribeck_friction``).

The reduced models hold a constant sliding friction (TOf in BO, TCf in CC). Static friction is
higher; it decays to the sliding level over the Stribeck speed v_s = 2 rad/s:

    T_s/J = σ·T_drive·exp(−(v/v_s)²)·tanh(v/v_ε),   v_ε = 0.05 rad/s

The tanh makes the friction a smooth function that opposes motion (v_ε is far below any speed
that matters). It acts on the output shaft in an opening (T_drive = BO) and on the camshaft in a
closing (T_drive = AC·g(θ1_start), the drive at latch release), i.e. at the start of motion.
σ = 0 is the reduced model.
"""

from __future__ import annotations

import math

from numba import njit

V_STRIBECK = 2.0   # [rad/s]
V_EPS = 0.05       # [rad/s]


@njit(cache=True, inline="always")
def stribeck_torque(omega, sigma, drive, v_s=V_STRIBECK, delta=2.0):
    """Extra friction torque per inertia [rad/s²] opposing ω [rad/s].

    Family (diagnosis): Stribeck speed ``v_s`` [rad/s] and exponent ``delta`` (1 … 2) of the
    decay exp(−(|ω|/v_s)^δ)."""
    if sigma == 0.0:
        return 0.0
    r = abs(omega) / v_s
    return sigma * drive * math.exp(-r ** delta) * math.tanh(omega / V_EPS)
