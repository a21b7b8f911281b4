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
def cam_load_factor(loss):
    """1/η [-] for loss 1 − η [-]."""
    return 1.0 / (1.0 - loss)
