"""Crank–rod linkage with an angle-dependent transmission ratio (``linkage_kinematics``).

The contact side is driven through a crank whose transmission ratio u(θ) is largest where the
crank is perpendicular to the rod (mid-stroke, θm = stroke/2) and falls towards the ends:

    u(θ)² = j(θ) = 1 − λ·sin²(θ − θm)

The equivalent inertia seen at the output shaft is J2·j(θ) and the contact-side (puffer) damping
CO·j(θ). Lagrange's equation with a position-dependent inertia gives the extra term

    j(θ)·θ'' + ½·j'(θ)·θ'² = Q(θ, θ')          j'(θ) = −λ·sin(2(θ − θm))

so the kinetic energy ½·j(θ)·θ'² changes only by the work of the generalised force Q.
λ = 0 is the reduced model's constant inertia.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def inertia_ratio(theta, lam, theta_mid, phase=0.0, second=0.0):
    """j(θ) [-] and j'(θ) [rad^-1] at output-shaft angle θ [rad] for strength λ [-].

    Family (diagnosis): the perpendicular position shifted by ``phase`` [rad] and a share
    ``second`` of the second harmonic, j = 1 − λ·[(1 − r)·sin²(ψ) + r·sin²(2ψ)], ψ = θ − θm − phase."""
    psi = theta - theta_mid - phase
    s = math.sin(psi)
    s2 = math.sin(2.0 * psi)
    j = 1.0 - lam * ((1.0 - second) * s * s + second * s2 * s2)
    jp = -lam * ((1.0 - second) * s2 + second * 2.0 * math.sin(4.0 * psi))
    return j, jp
