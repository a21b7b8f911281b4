"""Power lost in the cam–roller transmission (``cam_friction``), closing only.

The reduced model takes T21 = T12·h' (power conservation). With efficiency η < 1 the camshaft
must supply more torque than the output shaft receives:

    T21 = T12·h'/η

In Eq. 7 this replaces BC by BC/η everywhere, so it is exactly a change of the inertia factor:
the fitted BC absorbs it with no residual. The strength is 1 − η; 0 is the reduced model.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def cam_load_factor(loss, slope=0.0, u=0.5):
    """1/η [-] for loss 1 − η [-].

    Family (diagnosis): the loss varies along the rise, (1 − η)·(1 + slope·(2u − 1)) with u the
    rise fraction [-]; slope 0 (the prototype) is a constant efficiency."""
    return 1.0 / (1.0 - min(loss * (1.0 + slope * (2.0 * u - 1.0)), 0.9))
