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
def gas_torque(theta, pi_g, BO, stroke, kappa=KAPPA, ratio=VOLUME_RATIO):
    """Gas torque per J2 [rad/s²] opposing the opening at contact-side angle θ [rad], no leakage.

    Family (diagnosis): polytropic exponent ``kappa`` (1 isothermal … 1.4 adiabatic) and volume
    ratio ``ratio`` = θv/stroke."""
    if pi_g == 0.0 or theta <= 0.0:
        return 0.0
    tv = ratio * stroke
    x = min(theta, 0.95 * tv)
    p = (1.0 - x / tv) ** (-kappa) - 1.0
    p_ref = (1.0 - 1.0 / ratio) ** (-kappa) - 1.0
    return pi_g * BO * p / p_ref


@njit(cache=True, inline="always")
def leaky_gas(theta, omega, g, pi_g, BO, stroke, kappa, ratio, leak):
    """Gas torque per J2 [rad/s²] and dg/dt [1/s] with nozzle leakage (diagnosis family).

    g = ρ/ρ0 − 1 is the gas over-density, a state: the swept volume compresses it,
    dg/dt = (1 + g)·θ'/(θv − θ), and the nozzle lets it out at the rate ``leak`` [1/s],
    −leak·g. The pressure is polytropic, p/p0 = (1 + g)^κ. Without leakage this is
    :func:`gas_torque` exactly (g = θ/(θv − θ))."""
    tv = ratio * stroke
    x = min(max(theta, 0.0), 0.95 * tv)
    r = max(1.0 + g, 1e-6)
    p_ref = (1.0 - 1.0 / ratio) ** (-kappa) - 1.0
    torque = pi_g * BO * (r ** kappa - 1.0) / p_ref
    return torque, r * omega / (tv - x) - leak * g
