"""Average run length (ARL) of the winsorised CUSUM, for choosing k, h and z_cap.

Brook & Evans (1972) Markov-chain approximation: the in-control ARL (shift 0) is the mean number
of fits between false alarms, the out-of-control ARL the mean detection delay for a step shift.
The detector feeds the CUSUM self-starting scores (Hawkins 1987), which are independent N(0, 1)
while the breaker is in control even though its baseline is estimated, so the known-parameter ARL
computed here is the design ARL; bench/alarm_rates.py checks it by simulation.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy import optimize, special


def _increment_cdf(x: np.ndarray, shift: float, k: float, z_cap: float) -> np.ndarray:
    """P(X < x) for X = clip(Z + shift, -z_cap, z_cap) - k, Z ~ N(0, 1) [-]."""
    cdf = special.ndtr(x + k - shift)
    cdf = np.where(x <= -z_cap - k, 0.0, cdf)  # point mass at -z_cap - k
    return np.where(x > z_cap - k, 1.0, cdf)  # point mass at z_cap - k


def cusum_arl(shift: float, *, k: float, h: float, z_cap: float = np.inf,
              n_states: int = 300) -> float:
    """ARL of S_i = max(0, S_{i-1} + clip(z_i, -z_cap, z_cap) - k) reaching h, from S_0 = 0.

    shift : mean of z_i after the change [baseline sigmas]; 0 gives the in-control ARL
    k, h, z_cap : as in DriftSettings [z]
    Returns the ARL [fits] of this one-sided CUSUM (its mirror has the ARL of -shift).
    """
    w = 2.0 * h / (2 * n_states - 1)  # state j is S in [(j - 1/2) w, (j + 1/2) w); state 0 is S = 0
    centre = np.arange(n_states) * w
    upper = (np.arange(n_states) + 0.5) * w
    cdf = _increment_cdf(upper[None, :] - centre[:, None], shift, k, z_cap)
    r = np.diff(np.concatenate([np.zeros((n_states, 1)), cdf], axis=1), axis=1)
    arl = np.linalg.solve(np.eye(n_states) - r, np.ones(n_states))
    return float(arl[0])


def two_sided_arl(shift: float, *, k: float, h: float, z_cap: float = np.inf) -> float:
    """ARL of the two-sided scheme (both CUSUMs, alarm on either) [fits].

    Uses 1/ARL = 1/ARL+ + 1/ARL-, accurate when the two sides rarely run together (k >~ 0.5).
    """
    up = cusum_arl(shift, k=k, h=h, z_cap=z_cap)
    down = cusum_arl(-shift, k=k, h=h, z_cap=z_cap)
    return 1.0 / (1.0 / up + 1.0 / down)


@functools.lru_cache(maxsize=64)
def threshold_for_arl(arl: float, *, k: float, z_cap: float = np.inf) -> float:
    """Decision threshold h [z] whose one-sided in-control ARL is ``arl`` [fits] (Brook-Evans).

    The thresholds of the detector come from here, not from tuning: docs/alarms.md.
    """
    if not arl > 1:
        raise ValueError(f"target ARL must exceed 1 fit, got {arl}")
    lo, hi = 1e-3, 1.0
    while cusum_arl(0.0, k=k, h=hi, z_cap=z_cap) < arl:
        lo, hi = hi, hi * 2
        if hi > 100:
            raise ValueError(f"no threshold below 100 reaches an ARL of {arl:g} with k = {k}")
    return float(optimize.brentq(lambda h: cusum_arl(0.0, k=k, h=h, z_cap=z_cap) - arl, lo, hi,
                                 xtol=1e-6))
