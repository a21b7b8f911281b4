"""Hydraulic buffer with orifice flow (``orifice_buffer``), acting after α0 only.

Flow through an orifice gives a pressure drop ∝ Q·|Q|, so the buffer force grows with v·|v|
rather than v. The metering pin closes the orifice over the buffer stroke, the area falling to
half at full stroke, and the force rises as 1/A²:

    T_orifice/J2 = γ·DO·θ'·|θ'| / v_ref · a(θ)^-2,    a(θ) = 1 − ½·(θ − α0)/(stroke − α0)

with v_ref = 20 rad/s (about the speed at engagement). It adds to the reduced model's linear
DO·θ' term; γ = 0 is the reduced model.
"""

from __future__ import annotations

from numba import njit

V_REF = 20.0  # [rad/s]


@njit(cache=True, inline="always")
def orifice_torque(theta, omega, gamma, DO, alpha0, stroke):
    """Extra buffer torque per J2 [rad/s²] (opposes θ'); zero before α0."""
    if theta <= alpha0 or gamma == 0.0:
        return 0.0
    a = 1.0 - 0.5 * min((theta - alpha0) / (stroke - alpha0), 1.0)
    return gamma * DO * omega * abs(omega) / V_REF / (a * a)
