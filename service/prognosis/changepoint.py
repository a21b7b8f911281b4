"""A path from the last change of slope, found on the history itself.

Pure, numpy/numba only. The alarm's change point is where the CUSUM last left zero; a path may
change its slope later (a seal that tears, a leak that stops, a refill, a sensor remounted). This
candidate is a straight line through the fits since an unknown change at fit tau, with a level
and a slope of its own before it:

    y_i = a + b phi(n_i) + 1{i < tau} (a' + b' phi(n_i)) + nuisances + e_i,     phi(n) = (n - d0) / S

tau has a uniform prior over a grid of the fits. Its predictive density of each fit given the fits
before it is the mixture over tau, weighted by each tau's posterior given only those earlier fits
(online Bayesian change-point detection with one change, Adams & MacKay 2007; the run length is
i - tau): a fit before tau sees the model without a change, so a change is believed only once
the fits after it have shown it. The forecast is the mixture over tau of each line's Student t
level, weighted by tau's posterior given every fit.
"""

from __future__ import annotations

import numpy as np

from service.prognosis.paths import FLAT_PRECISION, fit_path, lfo_log_density

GRID = 16  # candidate change points
MIN_AFTER = 8  # fits after a change a slope is drawn through
MIN_BEFORE = 3
# The change is looked for among the last RECENT fits (and the line drawn through them): a
# bounded cost per prognosis however long the basis, and a change of slope older than that is
# the alarm's change point's business.
RECENT = 400


def fit_change_point(n, y, w, nuis, nuis_prec, *, d0: float, scale_ops: float, prior_sd: float,
                     prior_dof: float, first: int):
    """The last-change-of-slope candidate. n [operations], y [unit], w [-]: the fits; nuis [m, q],
    nuis_prec [q]: nuisance columns and their prior precisions (sigma^-2 units, 0 flat).
    Returns ([(PathFit, posterior weight of its tau)], log predictive densities [m]) or None when
    the history is too short for a change."""
    if len(n) > RECENT:
        cut = len(n) - RECENT
        n, y, w = n[cut:], y[cut:], w[cut:]
        nuis = None if nuis is None else nuis[cut:]
        first = max(first - cut, 10)  # the restarted lines need a few fits before they predict
        lp_full_len = cut
    else:
        lp_full_len = 0
    m = len(n)
    taus = np.unique(np.linspace(max(MIN_BEFORE, first), m - MIN_AFTER, GRID).astype(int))
    taus = taus[(taus >= MIN_BEFORE) & (taus <= m - MIN_AFTER)]
    if taus.size == 0:
        return None
    phi = (n - d0) / scale_ops
    nuis = np.zeros((m, 0)) if nuis is None else nuis
    lps, designs = [], []
    for tau in taus:
        pre = (np.arange(m) < tau).astype(float)
        x = np.column_stack([np.ones(m), phi, pre, phi * pre, nuis])
        prec = np.concatenate([[0.0, 0.0, 0.0, 0.0], nuis_prec])
        lp = lfo_log_density(np.ascontiguousarray(x), y, w, np.where(prec > 0, prec, FLAT_PRECISION),
                             prior_sd ** 2, prior_dof, first)
        lps.append(lp)
        designs.append((x, prec))
    lp = np.array(lps)  # [T, m]
    finite = np.isfinite(lp).all(axis=0)
    # tau's posterior before fit i, from the fits first..i-1 (uniform prior)
    cum = np.cumsum(np.where(finite, lp, 0.0), axis=1)
    before = np.concatenate([np.zeros((len(taus), 1)), cum[:, :-1]], axis=1)
    before -= before.max(axis=0)
    post = np.exp(before)
    post /= post.sum(axis=0)
    with np.errstate(divide="ignore"):
        mixed = np.log((post * np.exp(lp - np.where(finite, lp.max(axis=0), 0.0))).sum(axis=0))
    mixed = np.where(finite, mixed + lp.max(axis=0), -np.inf)
    final = cum[:, -1] - cum[:, -1].max()
    weight = np.exp(final)
    weight /= weight.sum()
    out = []
    for tau, (x, prec), wt in zip(taus, designs, weight):
        if wt < 1e-3:
            continue
        f = fit_path(x, y, w, np.where(prec > 0, prec, FLAT_PRECISION),
                     prior_sd=prior_sd, prior_dof=prior_dof, shape=1.0, scale_ops=scale_ops, d0=d0)
        out.append((f, float(wt)))
    total = sum(wt for _, wt in out)
    mixed = np.concatenate([np.full(lp_full_len, -np.inf), mixed])
    return [(f, wt / total) for f, wt in out], mixed
