"""Closed-form response of a linear second-order segment x'' = -a·x + f - c·x'.

Both opening segments of Eq. 11 have this form with constant coefficients, so they are solved
exactly instead of integrated. All arguments broadcast, so a whole CMA-ES population is one call.
"""

from __future__ import annotations

import numpy as np


def damped_response(tau, a, c, f, x0, v0):
    """Position and velocity of x'' = -a·x + f - c·x' at elapsed time ``tau``.

    Parameters
    ----------
    tau : array_like
        Time since the segment started [s]; broadcasts with the coefficients.
    a : array_like
        Stiffness coefficient [s^-2], > 0.
    c : array_like
        Damping coefficient [s^-1], >= 0.
    f : array_like
        Constant forcing [rad s^-2].
    x0, v0 : array_like
        State at ``tau = 0`` [rad], [rad/s].

    Returns
    -------
    x, v : ndarray
        Position [rad] and velocity [rad/s]. Under-, critically and over-damped cases are all
        exact: the complex frequency covers the first and last, a series the middle one.
    """
    tau = np.asarray(tau, dtype=float)
    a = np.asarray(a, dtype=float)
    c = np.asarray(c, dtype=float)
    sigma = 0.5 * c
    omega2 = a - sigma * sigma
    omega = np.sqrt(omega2.astype(complex))
    x_eq = f / a
    c1 = x0 - x_eq
    c2 = v0 + sigma * c1
    wt = omega * tau
    cos_wt = np.cos(wt).real
    # sin(ωτ)/ω, with its limit τ where ω -> 0 (critical damping).
    small = np.abs(wt) < 1e-6
    safe_omega = np.where(np.abs(omega) > 0, omega, 1.0)
    sinc_t = np.where(small, tau * (1.0 - wt.real**2 / 6.0 + (wt.imag**2) / 6.0),
                      (np.sin(wt) / safe_omega).real)
    decay = np.exp(-sigma * tau)
    x = x_eq + decay * (c1 * cos_wt + c2 * sinc_t)
    v = decay * ((c2 - sigma * c1) * cos_wt - (sigma * c2 + omega2 * c1) * sinc_t)
    return x, v


def first_peak_time(a, c, t_max):
    """Time of the first velocity zero of a segment starting at rest below equilibrium [s].

    For an under-damped segment this is π/ω; an over- or critically damped one never turns
    back, so ``t_max`` is returned.
    """
    a = np.asarray(a, dtype=float)
    c = np.asarray(c, dtype=float)
    omega2 = a - 0.25 * c * c
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(omega2 > 0, np.pi / np.sqrt(np.where(omega2 > 0, omega2, 1.0)), t_max)
    return np.minimum(t, t_max)
