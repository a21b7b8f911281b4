"""Compliant insulating pull rod (``rod_elasticity``): two inertias instead of one.

The output shaft (inertia fraction 1 − μ, carries the springs, the buffer and the travel
sensor) and the contact side (fraction μ, carries the puffer and the contact loads) are linked
by a spring K and a damper C. Per J2, with φ the contact-side angle referred to the shaft:

    (1 − μ)·θ'' = Q_shaft − K·(θ − φ) − C·(θ' − φ')
         μ·φ''  = Q_contact + K·(θ − φ) + C·(θ' − φ')

The rod's natural frequency is f_rod = 150 Hz / √ε, so K = ω_rod²·μ(1 − μ) and
C = 2ζ·ω_rod·μ(1 − μ) with ζ = 0.05. The shaft rings after release and at buffer engagement.
ε = 0 is the rigid rod of the reduced model (integrated as one inertia).
"""

from __future__ import annotations

import math

from numba import njit

MASS_FRACTION = 0.35   # μ, contact-side share of the equivalent inertia [-]
F_REF = 150.0          # [Hz]
DAMPING_RATIO = 0.05   # ζ [-]


@njit(cache=True, inline="always")
def rod_coefficients(eps, zeta=DAMPING_RATIO):
    """K [s^-2] and C [s^-1] per J2 for compliance ε [-] (ε > 0) and damping ratio ζ [-].

    Family (diagnosis): ζ free, and the travel sensor on the shaft or the contact side of the
    rod (a reading θ + s·(φ − θ), s the ``sensor_side`` shape; the prototype's is 0)."""
    w = 2.0 * math.pi * F_REF / math.sqrt(eps)
    mm = MASS_FRACTION * (1.0 - MASS_FRACTION)
    return w * w * mm, 2.0 * zeta * w * mm
