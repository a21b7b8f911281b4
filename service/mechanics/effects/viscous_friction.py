"""Bearing friction proportional to speed (``viscous_friction``).

    T_v/J2 = ν·CO·θ'

on the output shaft (opening: θ' of the shaft; closing: θ2' = h'·θ1'). It adds to the puffer
damping CO, which is a structural constant held fixed in the fit, so it is not the same as a
change of any estimated parameter. ν = 0 is the reduced model.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def viscous_torque(omega, nu, CO, slope=0.0, u=0.5):
    """Viscous friction torque per J2 [rad/s²] opposing ω [rad/s].

    Family (diagnosis): the coefficient varies linearly along the stroke, ν·(1 + slope·(2u − 1))
    with u the stroke fraction [-]."""
    return nu * CO * omega * (1.0 + slope * (2.0 * u - 1.0))
