"""Statistics of a residual: per-phase RMS against the noise floor, significance, whiteness."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from .data import gap_rms


def phase_stats(d, data, bounds, tau):
    """Per phase {name, t0_s, t1_s, rmse_rad, gap_rad, ratio_to_noise, p_value}.

    ``d``: block-mean residual [rad]; ``bounds``: [(name, t0, t1)] in model time; the output
    times are in capture time [s from the first sample].
    """
    out = []
    tm = data.t - tau
    for name, a, b in bounds:
        sel = (tm >= a) & (tm < b) if name not in ("approach", "end") else (tm >= a) & (tm <= b + 1e-9)
        g = gap_rms(d[sel], data.count[sel], data.noise)
        rmse = float(np.sqrt(g * g + data.noise**2))
        stat = float(np.sum(d[sel] ** 2 * data.count[sel])) / data.noise**2
        p = float(chi2.sf(stat, max(int(sel.sum()), 1))) if sel.any() else 1.0
        out.append({"name": name, "t0_s": data.t_start + tau + a, "t1_s": data.t_start + tau + b,
                    "rmse_rad": rmse, "gap_rad": g, "ratio_to_noise": rmse / data.noise,
                    "p_value": p, "samples": int(data.count[sel].sum())})
    return out


def whiteness(d, data, lags: int = 10):
    """Ljung–Box p-value of the normalised block residual (small: structured, not noise)."""
    from statsmodels.stats.diagnostic import acorr_ljungbox

    z = d * np.sqrt(data.count) / data.noise
    if z.size <= lags + 2:
        return 1.0
    return float(acorr_ljungbox(z, lags=[lags], return_df=True)["lb_pvalue"].iloc[0])


def excess_p(d, data):
    """p-value that the block residual is noise alone (χ² test on Σ count·d²/σ²)."""
    stat = float(np.sum(d * d * data.count)) / data.noise**2
    return float(chi2.sf(stat, d.size))
