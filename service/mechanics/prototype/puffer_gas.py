"""Gas compression in the puffer cylinder (``puffer_gas``), a position-dependent force.

The moving contact compresses the puffer volume adiabatically (κ = 1.4); the cylinder would be
fully compressed at θv = 1.6·stroke. The pressure force on the contact side, per J2:

    T_gas/J2 = π_g·BO·p(θ)/p(stroke),   p(θ) = (1 − θ/θv)^(−κ) − 1

It is small early and grows mid to late in the opening. It is conservative (it stores energy
in the gas, potential U_gas = ∫ T_gas dθ), unlike the reduced model's linear damping CO·θ'.
π_g = 0 is the reduced model.
"""

from __future__ import annotations

from numba import njit

KAPPA = 1.4
VOLUME_RATIO = 1.6  # θv / stroke


@njit(cache=True, inline="always")
def gas_torque(theta, pi_g, BO, stroke):
    """Gas torque per J2 [rad/s²] opposing the opening at contact-side angle θ [rad]."""
    if pi_g == 0.0 or theta <= 0.0:
        return 0.0
    tv = VOLUME_RATIO * stroke
    x = min(theta, 0.95 * tv)
    p = (1.0 - x / tv) ** (-KAPPA) - 1.0
    p_ref = (1.0 - 1.0 / VOLUME_RATIO) ** (-KAPPA) - 1.0
    return pi_g * BO * p / p_ref
