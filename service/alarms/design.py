"""Average run length (ARL) of the winsorised CUSUM, for choosing k, h and z_cap.

Brook & Evans (1972) Markov-chain approximation, with known baseline parameters: the in-control
ARL (shift 0) is the mean number of fits between false alarms, the out-of-control ARL the mean
detection delay for a step shift. The effect of a baseline estimated from only n fits is not in
here; docs/alarms.md gives it by simulation (tests/alarms/simulate_rates.py).
"""

from __future__ import annotations

import numpy as np
from scipy import special


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
