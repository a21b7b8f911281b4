"""Progressive spring stiffness (``spring_nonlinearity``).

A helical spring with closing coils stiffens as it is compressed: F = k·x·(1 + β·x/x_ref).

Opening (the opening spring, compression x = rO·(X1 − θ), X1 = xO1/rO, x_ref = xO1):

    T/J2 = −AO·θ + BO + β·AO·(X1 − θ)²/X1

Closing (the closing spring, compression x = xC0 − rC·(1 − cos θ1), x_ref = xC0):

    drive = AC·g(θ1)·(1 + β·x/xC0)

Over the 1 rad stroke the opening extra term is nearly linear in θ, so AO and BO absorb most of
it. β = 0 is the reduced model.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def opening_spring_extra(theta, beta, AO, X1, power=2.0):
    """Extra opening-spring torque per J2 [rad/s²] (drives the opening).

    Family (diagnosis): F = k·x·(1 + β·(x/x_ref)^(p−1)), p = ``power`` 2 (quadratic) … 3
    (cubic); β < 0 is a degressive spring."""
    X = max(X1 - theta, 0.0)
    return beta * AO * X1 * (X / X1) ** power


@njit(cache=True, inline="always")
def closing_spring_factor(theta1, beta, xC0, rC, power=2.0):
    """Multiplier on the closing drive AC·g(θ1) [-]."""
    x = max(xC0 - rC * (1.0 - math.cos(theta1)), 0.0) / xC0
    return 1.0 + beta * x ** (power - 1.0)
