"""First passage of a degradation path through its limit: closed forms and a seeded simulation.

Pure, numpy/scipy only.

- ``first_passage``: a Wiener path with a known drift nu and diffusion q per operation has an
  inverse Gaussian first passage (Si et al. 2012, eq. 6; Chhikara & Folks 1989); a gamma path
  with the same mean and variance per operation (van Noortwijk 2009) has crossed by t when its
  loss exceeds the distance, the regularised upper incomplete gamma function.
- ``simulate_passage``: when the drift itself wanders (a random walk of the drift, the
  adaptive-drift Wiener model of Si, Wang, Hu, Chen & Zhou 2013, MSSP 35, carried into the
  future rather than frozen at its filtered value), or the drift acts on a transformed time
  scale Lambda(n) (Si et al. 2012; Whitmore & Schenkelberg 1997), no closed form holds for the
  general case. The state (level, drift) is drawn from its posterior and moved forward on the
  grid of operations ahead with its exact Gaussian transition (the drift's random walk
  integrated into the level: var q_b D^3 / 3, cov q_b D^2 / 2), and the level's own Wiener part
  crossing between two grid points is counted by the Brownian bridge's crossing probability
  exp(-2 d1 d2 / (q D)) (e.g. Glasserman 2004, sec. 6.4). A gamma path moves by gamma
  increments of the current drift (none while the drift is not toward the limit).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy import special


def first_passage(delta, nu, q, t, kind="wiener"):
    """P(T <= t) of a path at distance ``delta`` [unit] from its limit, drift ``nu`` toward it
    [unit/op], diffusion variance ``q`` per op [unit^2/op], after ``t`` operations (arrays,
    broadcast). Wiener: the inverse Gaussian first passage (defective when nu <= 0); gamma: a
    monotone path with the same mean and variance per op; q = 0: the deterministic crossing."""
    delta, nu, q, t = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (delta, nu, q, t)))
    out = np.where(delta <= 0, 1.0, 0.0)
    live = delta > 0
    det = live & (q <= 0)
    out = np.where(det & (nu * t >= delta), 1.0, out)
    st = live & (q > 0) & (t > 0)
    if kind == "gamma":
        ok = st & (nu > 0)
        a = np.where(ok, nu * nu * t / np.where(ok, q, 1.0), 1.0)
        x = np.where(ok, delta * nu / np.where(ok, q, 1.0), 1.0)
        return np.where(ok, special.gammaincc(a, x), out)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        sq = np.sqrt(np.where(st, q * t, 1.0))
        p1 = special.ndtr((nu * t - delta) / sq)
        expo = 2.0 * nu * delta / np.where(st, q, 1.0) + special.log_ndtr((-nu * t - delta) / sq)
        p2 = np.exp(np.minimum(expo, 0.0))
    return np.where(st, np.clip(p1 + p2, 0.0, 1.0), out)


@njit(cache=True)
def _passage_kernel(delta, nu, q, qd, dt, dl, gamma, seed):
    """First grid index each draw has crossed by (len(dt) if never): the loop of
    ``simulate_passage`` (seeded numba generator)."""
    np.random.seed(seed)
    k, g = delta.size, dt.size
    out = np.full(k, g)
    for i in range(k):
        d, v = delta[i], nu[i]
        if d <= 0:
            out[i] = 0
            continue
        for j in range(g):
            step, dlam = dt[j], dl[j]
            if step <= 0:
                continue
            dv = math.sqrt(qd[i] * step) * np.random.standard_normal()
            move = (v + 0.5 * dv) * dlam + math.sqrt(qd[i] * step / 12.0) * dlam * np.random.standard_normal()
            if gamma:
                var = q[i] * step
                if move > 0 and var > 0:
                    inc = np.random.gamma(move * move / var, var / move)
                else:
                    inc = max(move, 0.0)
                d_new = d - inc
                hit = d_new <= 0
            else:
                d_new = d - move - math.sqrt(q[i] * step) * np.random.standard_normal()
                hit = d_new <= 0
                if not hit and q[i] > 0:
                    hit = np.random.random() < math.exp(-2.0 * d * d_new / (q[i] * step))
            if hit:
                out[i] = j
                break
            d = d_new
            v = v + dv
    return out


def simulate_passage(delta, nu, q, q_drift, t, *, kind="wiener", clock=None, seed=2013):
    """P(crossed by each of ``t``) [-] from draws of the state now.

    delta [K] : distance to the limit [unit] (> 0 not crossed); nu [K] : drift toward it [unit
    per unit of the clock]; q [K] : the level's diffusion [unit^2/op]; q_drift [K] : the drift's
    random-walk variance [(unit per clock unit)^2 per op]; t [G] : operations ahead, increasing,
    t[0] >= 0; clock(t) : the drift's time scale Lambda at t operations ahead, minus Lambda now
    (None: the operations themselves). Returns the fraction of the K draws crossed by each t.
    """
    delta, nu, q, qd = (np.ascontiguousarray(a, dtype=float) for a in (delta, nu, q, q_drift))
    t = np.asarray(t, dtype=float)
    lam = t if clock is None else np.asarray(clock(t), dtype=float)
    dt = np.diff(np.concatenate([[0.0], t]))
    dl = np.diff(np.concatenate([[0.0], lam]))
    idx = _passage_kernel(delta, nu, q, qd, dt, dl, kind == "gamma", seed)
    counts = np.bincount(idx, minlength=t.size + 1)[:t.size]
    return np.cumsum(counts) / delta.size
