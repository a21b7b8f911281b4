"""Contact fingers from contact touch onwards (``contact_wipe``), closing only.

From touch (θ2 ≥ θt = 0.7 of the cam rise) the moving contact slides into the finger cluster:
a friction load and a wipe spring that grows over the remaining travel, per J2:

    T_w/J2 = w·CC·[½·tanh(θ2'/v_ε) + ½·(θ2 − θt)/(θ2_end − θt)]    θ2 ≥ θt, else 0

with v_ε = 0.05 rad/s. It opposes closing near the end only. w = 0 is the reduced model.
"""

from __future__ import annotations

import math

from numba import njit

TOUCH_FRACTION = 0.7
V_EPS = 0.05


@njit(cache=True, inline="always")
def wipe_torque(theta2, omega2, w, CC, theta_touch, theta_end, spring_share=0.5):
    """Contact load per J2 [rad/s²] opposing closing.

    Family (diagnosis): the touch position (``theta_touch``) and the split of the load between
    the wipe spring (``spring_share``) and the finger friction are free."""
    if w == 0.0 or theta2 < theta_touch:
        return 0.0
    s = (theta2 - theta_touch) / (theta_end - theta_touch)
    return w * CC * ((1.0 - spring_share) * math.tanh(omega2 / V_EPS) + spring_share * s)
