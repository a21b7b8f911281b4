"""``none`` decided before any scorer (issue 54 item 5): is what the reduced model leaves on
these captures consistent with the noise?

The reduced model shares nothing between captures (each capture has its own state and τ, and
the sensor's own zero and gain), so its residual on a capture is already held out from the
others: nothing learnt on one capture enters another's residual. The test asks whether a smooth
gap of any shape sits in those residuals, with a false rate fixed by design.

Per capture i, in the units of ``windows`` (each block mean whitened by the pre-trigger σ_i of
its capture) and with the capture's nuisance tangent (state, τ, the sensor's zero and gain)
projected out, P⊥_i:

* y_i = P⊥_i r_i the projected residual (n_i rows, ν0_i = n_i − rank N_i free);
* X_i = P⊥_i B_i, B_i the capture's own cubic B-splines with knots every ``NOISE_KNOT_S``
  (2 ms: any smooth gap below ~250 Hz, the band every catalogued effect and the discrepancy live
  in), q_i = rank X_i; RSS0_i = ‖y_i‖², RSS1_i = ‖y_i − X_i X_i⁺ y_i‖².

The nested F statistic pooled over the independent captures,

    F = [Σ (RSS0_i − RSS1_i) / Σ q_i] / [Σ RSS1_i / Σ (ν0_i − q_i)],

follows F(Σq, Σ(ν0 − q)) exactly when the reduced model is right and the block means' noise is
white Gaussian of any scale (the denominator estimates it: no σ is assumed, so a sensor noisier
in motion than at rest does not refuse ``none``). Noise above the splines' band (a realistic
sensor's struck modes, 300–1500 Hz) enters the denominator more than the numerator: the test is
then conservative, never looser. The in-motion AR filter of ``predictive`` is not applied here:
it is fitted to what a spline leaves (a high-passed residual) and floored, which biases F
upwards by 4-16 % on white noise (measured on three healthy groups: F 1.04-1.16 filtered,
0.94-1.04 unfiltered). ``none`` is decided when F stays below its 1 − ``LEVEL`` quantile.

The level. ``LEVEL`` = 0.01 is the designed false rate: a healthy breaker's group is refused
``none`` once in a hundred diagnoses. It is a tenth of the 90 % set's designed miss rate (0.10),
so that deciding ``none`` by this test moves the set's coverage by at most 0.01, and it is the
same order as the alarms' design (a false warning is a maintenance visit: docs/alarms.md).
A refused ``none`` leaves the set (P(none) = 0 there): the other hypotheses get the scorer's
probabilities conditioned on "not none" (``diagnose.decide_none``). The test's measured false rate is bench/gap_none_rate.py's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import f as f_dist

from .noise import NOISE_KNOT_S, _orth, spline_basis

LEVEL = 0.01   # the designed false rate (see the module docstring for why this value)


@dataclass
class NoneTest:
    """The test's statistic F, its degrees of freedom, p-value, level and decision."""

    statistic: float
    df_gap: int
    df_noise: int
    p_value: float
    level: float
    consistent: bool

    def to_dict(self) -> dict:
        return {"statistic": self.statistic, "df_gap": self.df_gap, "df_noise": self.df_noise,
                "p_value": self.p_value, "level": self.level, "none": self.consistent,
                "test": "nested F on the reduced model's residual: per-capture 2 ms splines against the "
                        "residual they leave"}


def capture_terms(cw) -> tuple[float, float, int, int]:
    """(RSS0, RSS1, q, ν0) of one capture (``cw``: a ``windows.CaptureWindow``, whose ``Q`` is
    the orthonormal basis of its nuisance tangent)."""
    Q = cw.Q
    y = cw.r - Q @ (Q.T @ cw.r)
    t = cw.data.t
    B = spline_basis(t, float(t[0]), float(t[-1]) + 1e-9, max(NOISE_KNOT_S, 4 * float(np.median(np.diff(t)))))
    X = B * cw.data.weight[:, None]
    X = X - Q @ (Q.T @ X)
    Xq = _orth(X)
    rss0 = float(y @ y)
    e = y - Xq @ (Xq.T @ y)
    return rss0, float(e @ e), int(Xq.shape[1]), int(y.size - Q.shape[1])


def none_test(windows, level: float = LEVEL) -> NoneTest:
    """The nested F test of the module docstring over ``windows.captures``."""
    terms = [capture_terms(cw) for cw in windows.captures]
    d_rss = sum(a - b for a, b, _, _ in terms)
    rss1 = sum(b for _, b, _, _ in terms)
    q = sum(t[2] for t in terms)
    nu = sum(t[3] - t[2] for t in terms)
    if q == 0 or nu <= 0 or rss1 <= 0:
        # no room for a gap or for the noise: nothing to test against, so nothing is refused
        return NoneTest(0.0, q, nu, 1.0, level, True)
    F = (d_rss / q) / (rss1 / nu)
    p = float(f_dist.sf(F, q, nu))
    return NoneTest(float(F), int(q), int(nu), p, float(level), bool(p >= level))
