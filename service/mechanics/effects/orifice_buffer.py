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
def orifice_torque(theta, omega, gamma, DO, alpha0, stroke, n=2.0, metering=0.5, free=0.0):
    """Extra buffer torque per J2 [rad/s²] (opposes θ'); zero before α0 + ``free`` [rad].

    Family (diagnosis): the force grows as |θ'|ⁿ (n 1 laminar … 2 turbulent), the metering pin
    closes the area by the fraction ``metering`` over the buffer stroke. The prototype's own form
    is n = 2, metering 0.5, no free travel."""
    start = alpha0 + free
    if theta <= start or gamma == 0.0:
        return 0.0
    a = 1.0 - metering * min((theta - start) / (stroke - start), 1.0)
    w = abs(omega) / V_REF
    return gamma * DO * omega * w ** (n - 1.0) / (a * a)
