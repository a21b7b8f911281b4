"""Bayesian online change points in full (Adams & MacKay 2007): the run-length recursion over a
path made of segments, each a line or a level that holds still, and the chance of a change still
to come before the crossing.

Pure, numpy/numba only. The compensated values are a sequence of segments; within one,

    y_i = a + b (Phi_i - Phi_s) + sum_j h_j s_j(i) + e_i,     e_i ~ N(0, sigma^2 / w_i),  Phi = (n - d0) / S

with s the segment's first fit. A segment is *sloped* (b free) or *flat* (b = 0: the leak
stopped, the buffer was refilled, the spring settled); a new segment is either with probability
1/2 (the uniform prior over the two). Its prior (proper, as the recursion needs a predictive at
run length 0): a ~ N(c, D^2) with c the detector's baseline and D the farthest any fit of the
window lies from it plus 3 sigma (every level the window has seen is within one sd), b ~ N(0,
D^2) per basis length (a slope that crosses the window's whole range in one basis length is one
sd), nuisances with their own priors, sigma^2 the baseline's scaled-inverse-chi^2 prior (normal
inverse gamma: the predictive is Student t).

The recursion (Adams & MacKay 2007, Algorithm 1): before fit i, every hypothesis (run length,
kind) carries P(hypothesis | fits before i); a change happens before fit i with the hazard H_i =
1 - exp(-dn_i / lambda) (a constant hazard per operation, their eq. 5 with the geometric prior
on run lengths), so the new hypotheses "a segment starts at fit i" get H_i of the mass and the
others keep 1 - H_i; each is scored by its Student t predictive of fit i and renormalised. The
family's one-step density of fit i is the sum over hypotheses of mass times predictive.

The hazard's scale lambda [operations] is learnt, not tuned: lambda has a uniform prior over a
grid of half-decades from 100 to 10 000 operations (from a change every few months at one
opening a day to one per IEC 62271-100 class M2 life), and its posterior is the evidence of each
(the hazard's hyper-parameter by its marginal likelihood, as Turner, Saatci & Rasmussen 2009
learn it; here on a grid). Run lengths whose mass falls below 1e-6 are pruned (their eq. 3 loses
nothing visible; Adams & MacKay sec. 2.4 discuss the same truncation).

The forecast: the posterior over (run length, kind) at the last fit gives the current segment's
level and slope; ahead, a change still comes with the learnt hazard, keeping the level and
drawing a new slope from the segment prior (flat with probability 1/2). The crossing's
probability is simulated with those future changes (seeded), and ``change_before_crossing`` is
the share of crossing draws that changed pace before they crossed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit

from service.prognosis.wiener import SIM_DRAWS, mixed_log_density, share_draws, simulation_grid

HAZARD_SCALES = (100.0, 316.0, 1000.0, 3160.0, 10000.0)  # lambda grid [operations]
# Run lengths below MIN_MASS are pruned (the truncation Adams & MacKay sec. 2.4 discuss): the
# forecast reads no probability finer than Monte Carlo's 1/SIM_DRAWS = 1e-3, so 1e-6 is far below it.
MIN_MASS = 1e-6
# A cost cap, not derived: the recursion carries at most MAX_HYPOTHESES (run length, kind) pairs
# per fit (its cost O(m x 40)); with a flat and a sloped kind that is 20 run lengths. What the cap
# drops (the mass beyond the 40 largest) is not measured; issue 55 item 2 leaves it open.
MAX_HYPOTHESES = 40
# Also a cost cap, not derived: the forecast simulates the 12 most probable current segments;
# each gets at least MIN_SIM_DRAWS = 64 paths, 12 x 64 = 768 of SIM_DRAWS = 1000, so at least a
# quarter of the paths are still shared by weight.
MAX_SEGMENTS = 12
# The change is looked for among the last RECENT fits (and the segments drawn through them): a
# bounded cost per prognosis however long the basis.
RECENT = 400
SEED = 2007
FLAT_SHARE = 0.5  # a new segment is flat or sloped with equal prior probability


@njit(cache=True)
def run_length_recursion(y, w, phi, nuis, nuis_var, a0, va, vb, prior_sd2, prior_dof, dn, lam, first):
    """Adams & MacKay's recursion for one hazard scale ``lam`` [operations].

    y, w, phi, dn [m]: values, precisions, the clock (n - d0) / S, operations since the previous
    fit; nuis [m, q], nuis_var [q]: nuisance columns and their prior variances [sigma^2 units];
    a0 [unit], va, vb [sigma^2 units]: the level's prior mean and variance, the slope's variance.
    Returns (log one-step densities [m] (-inf before ``first``), and at the last fit the
    hypotheses' mass [R], kind [R] (0 sloped, 1 flat), start index [R], state mean [R, p],
    scale matrix [R, p, p], ssr [R], count [R]).
    """
    m = y.size
    q = nuis.shape[1]
    p = 2 + q
    cap = MAX_HYPOTHESES + 2
    mass = np.zeros(cap)
    kind = np.zeros(cap, np.int64)
    start = np.zeros(cap, np.int64)
    beta = np.zeros((cap, p))
    cov = np.zeros((cap, p, p))
    ssr = np.zeros(cap)
    cnt = np.zeros(cap)
    live = 0
    out = np.full(m, -np.inf)
    for i in range(m):
        hz = 1.0 - math.exp(-dn[i] / lam) if i > 0 else 1.0
        # a new segment starting at fit i, of either kind
        for j in range(live):
            mass[j] *= 1.0 - hz
        for kk in range(2):
            mass[live] = hz * (FLAT_SHARE if kk == 1 else 1.0 - FLAT_SHARE)
            kind[live] = kk
            start[live] = i
            beta[live, :] = 0.0
            beta[live, 0] = a0
            cov[live, :, :] = 0.0
            cov[live, 0, 0] = va
            cov[live, 1, 1] = vb if kk == 0 else 0.0
            for j in range(q):
                cov[live, 2 + j, 2 + j] = nuis_var[j]
            ssr[live] = 0.0
            cnt[live] = 0.0
            live += 1
        total = 0.0
        best = -np.inf
        logs = np.empty(live)
        x = np.empty(p)
        for j in range(live):
            x[0] = 1.0
            x[1] = phi[i] - phi[start[j]]
            for t in range(q):
                x[2 + t] = nuis[i, t]
            cx = cov[j] @ x
            f = 1.0 / w[i] + x @ cx
            e = y[i] - x @ beta[j]
            dof = prior_dof + cnt[j]
            v = (prior_dof * prior_sd2 + ssr[j]) / dof * f
            lg = (math.lgamma(0.5 * (dof + 1.0)) - math.lgamma(0.5 * dof) - 0.5 * math.log(dof * math.pi * v)
                  - 0.5 * (dof + 1.0) * math.log1p(e * e / v / dof))
            logs[j] = lg
            if lg > best:
                best = lg
            k = cx / f
            beta[j] = beta[j] + k * e
            cov[j] = cov[j] - np.outer(k, cx)
            ssr[j] += e * e / f
            cnt[j] += 1.0
        for j in range(live):
            mass[j] *= math.exp(logs[j] - best)
            total += mass[j]
        if i >= first:
            out[i] = math.log(total) + best
        for j in range(live):
            mass[j] /= total
        # prune: drop tiny masses, then keep the MAX_HYPOTHESES largest (compacting in place)
        small = 0
        for j in range(live):
            if mass[j] < MIN_MASS:
                small += 1
        if small == 0 and live <= MAX_HYPOTHESES:
            continue
        if live - small > MAX_HYPOTHESES:
            cut = np.sort(mass[:live])[live - MAX_HYPOTHESES]
        else:
            cut = MIN_MASS
        keep = 0
        for j in range(live):
            if mass[j] >= cut and keep < MAX_HYPOTHESES:
                if keep != j:
                    mass[keep] = mass[j]
                    kind[keep] = kind[j]
                    start[keep] = start[j]
                    beta[keep] = beta[j]
                    cov[keep] = cov[j]
                    ssr[keep] = ssr[j]
                    cnt[keep] = cnt[j]
                keep += 1
        if keep == 0:  # every mass tiny: keep the largest
            j = np.argmax(mass[:live])
            mass[0], kind[0], start[0], ssr[0], cnt[0] = mass[j], kind[j], start[j], ssr[j], cnt[j]
            beta[0] = beta[j]
            cov[0] = cov[j]
            keep = 1
        live = keep
        s = mass[:live].sum()
        mass[:live] /= s
    return out, mass[:live].copy(), kind[:live].copy(), start[:live].copy(), beta[:live].copy(), \
        cov[:live].copy(), ssr[:live].copy(), cnt[:live].copy()


@dataclass(frozen=True)
class SegmentFit:
    """The current segment under one hypothesis: level now and slope, Student t.

    beta : [L now, b] [unit, unit per basis length]; cov : their scale matrix [unit^2]; dof;
    kind : "sloped" | "flat"; start_n : the segment's first fit's operation count; n_now;
    scale_ops : S; hazard : the learnt change rate [1/operation]; slope_var : the segment
    prior's slope variance [unit^2 per basis length^2]
    """

    beta: np.ndarray
    cov: np.ndarray
    dof: float
    sd: float
    kind: str
    start_n: float
    n_now: float
    scale_ops: float
    hazard: float
    slope_var: float
    variant: str = "since the last change"
    shape: float = 1.0
    sim_draws: int = SIM_DRAWS
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    def level(self, n):
        """(mean, scale) of the level after operation ``n`` in this segment [unit] (Student t)."""
        phi = (np.asarray(n, dtype=float) - self.n_now) / self.scale_ops
        mean = self.beta[0] + self.beta[1] * phi
        var = self.cov[0, 0] + 2 * phi * self.cov[0, 1] + phi * phi * self.cov[1, 1]
        return mean, np.sqrt(np.maximum(var, 0.0))

    def crossing_probability(self, limit: float, direction: str, n: np.ndarray) -> np.ndarray:
        """P(crossed ``limit`` by operation ``n``) [-], future changes of pace included."""
        t = np.maximum(np.asarray(n, dtype=float) - self.n_now, 0.0)
        grid_t, cdf, _ = self.simulated(limit, direction, float(t.max()) if t.size else 0.0)
        return np.interp(t, grid_t, cdf)

    def simulated(self, limit: float, direction: str, t_max: float = 0.0):
        """(operations ahead, P(crossed by then), P(a change before the crossing | crossed within
        the grid))."""
        key = (limit, direction)
        have = self._cache.get(key)
        if have is None or have[0][-1] < t_max:
            top = max(1e4, 2.0 * t_max)
            grid_t = simulation_grid(top)
            have = _simulate_segments(self, limit, direction, grid_t)
            self._cache[key] = have
        return have


@njit(cache=True)
def _segment_kernel(d0, v0, g, slope_sd, hazard, grid_t, seed):
    """(first grid index crossed by [K] (G: never), whether the pace changed before it [K]):
    lines from (distance d0, speed v0 toward the limit), a change of pace at the hazard's rate
    at a uniform time within a step, the level held, the new speed flat with FLAT_SHARE or
    N(0, slope_sd^2 g) (g the draw's t scale)."""
    np.random.seed(seed)
    k, gsz = d0.size, grid_t.size
    idx = np.full(k, gsz)
    changed = np.zeros(k, np.bool_)
    for i in range(k):
        d, v = d0[i], v0[i]
        if d <= 0:
            idx[i] = 0
            continue
        prev = 0.0
        for j in range(gsz):
            step = grid_t[j] - prev
            prev = grid_t[j]
            if step <= 0:
                continue
            if np.random.random() < -math.expm1(-hazard * step):
                at = np.random.random() * step
                if d - v * at <= 0:
                    idx[i] = j
                    break
                d -= v * at
                changed[i] = True
                v = 0.0 if np.random.random() < FLAT_SHARE else slope_sd * math.sqrt(g[i]) * np.random.standard_normal()
                d -= v * (step - at)
            else:
                d -= v * step
            if d <= 0:
                idx[i] = j
                break
    return idx, changed


def _simulate_segments(seg: SegmentFit, limit: float, direction: str, grid_t: np.ndarray):
    rng = np.random.default_rng(SEED)
    k = seg.sim_draws
    sign = 1.0 if direction == "falling" else -1.0
    cov = 0.5 * (seg.cov + seg.cov.T)
    g = math.sqrt(seg.dof) / np.sqrt(rng.chisquare(seg.dof, k))
    if cov[1, 1] > 0:
        chol = np.linalg.cholesky(cov + 1e-12 * abs(cov).max() * np.eye(2))
        z = rng.standard_normal((k, 2)) @ chol.T * g[:, None]
    else:
        z = np.column_stack([math.sqrt(max(cov[0, 0], 0.0)) * rng.standard_normal(k), np.zeros(k)]) * g[:, None]
    d = sign * (seg.beta[0] + z[:, 0] - limit)  # distance to go [unit]
    v = -sign * (seg.beta[1] + z[:, 1]) / seg.scale_ops  # speed toward the limit [unit/op]
    slope_sd = math.sqrt(max(seg.slope_var, 0.0)) / seg.scale_ops
    idx, changed = _segment_kernel(d, v, g * g, slope_sd, seg.hazard, grid_t, SEED)
    counts = np.bincount(idx, minlength=grid_t.size + 1)[:grid_t.size]
    crossed = idx < grid_t.size
    share = float((changed & crossed).sum() / max(crossed.sum(), 1))
    return grid_t, np.cumsum(counts) / k, share


STEP_FITS = 20  # fits on either side of a change a line is drawn through to measure its step


def level_step(n, y, w, s: int, sd: float):
    """(the level's step at fit ``s`` [unit], its sd [unit]): a line through up to STEP_FITS fits
    before ``s`` and one through as many from ``s`` on, both evaluated at ``s``; (None, None)
    with fewer than 3 on a side."""
    lo, hi = max(0, s - STEP_FITS), min(len(n), s + STEP_FITS)
    if s - lo < 3 or hi - s < 3:
        return None, None
    at = n[s]
    levels, vars_ = [], []
    for sl in (slice(lo, s), slice(s, hi)):
        x = np.column_stack([np.ones(sl.stop - sl.start), n[sl] - at])
        a = (x.T * w[sl]) @ x
        inv = np.linalg.inv(a + 1e-12 * np.eye(2))
        beta = inv @ ((x.T * w[sl]) @ y[sl])
        levels.append(beta[0])
        vars_.append(sd * sd * inv[0, 0])
    return float(levels[1] - levels[0]), float(math.sqrt(vars_[0] + vars_[1]))


@dataclass(frozen=True)
class ChangePointFamily:
    """The segments at the last fit: candidates, their weights (run-length posterior times the
    hazard's), the family's one-step log densities, the learnt hazard, and the most probable
    last change (its fit index within the window, and the level step there [unit] with its sd)."""

    components: list
    weights: np.ndarray
    log_density: np.ndarray
    hazard: float
    hazard_posterior: dict
    last_change: int | None
    step: float | None
    step_sd: float | None
    flat_now: float


def fit_change_points(n, y, w, nuis, nuis_var, *, centre: float, scale_ops: float, prior_sd: float,
                      prior_dof: float, first: int, d0: float = 0.0, hazards=HAZARD_SCALES):
    """The change-point family over the fits (n [operations], y [unit], w [-]), nuisance columns
    ``nuis`` [m, q] with prior variances ``nuis_var`` [sigma^2 units] (inf: given a broad proper
    prior of the level's), the segments' level prior centred on ``centre`` [unit]. Returns a
    ChangePointFamily, or None when the window is too short."""
    n, y, w = (np.asarray(a, dtype=float) for a in (n, y, w))
    m_all = len(n)
    cut = max(0, m_all - RECENT)
    n, y, w = n[cut:], y[cut:], w[cut:]
    nuis = np.zeros((len(n), 0)) if nuis is None else np.asarray(nuis, dtype=float).reshape(m_all, -1)[cut:]
    first = max(first - cut, 1)
    m = len(n)
    if m < 10:
        return None
    s2 = prior_sd ** 2
    reach = float(np.abs(y - centre).max()) + 3.0 * prior_sd
    va = vb = reach ** 2 / s2
    nv = np.asarray(nuis_var, dtype=float)
    nv = np.where(np.isfinite(nv), nv, va)
    phi = (n - d0) / scale_ops
    dn = np.concatenate([[0.0], np.diff(n)])
    lps, finals, evid = [], [], []
    for lam in hazards:
        lp, mass, kind, start, beta, cov, ssr, cnt = run_length_recursion(
            np.ascontiguousarray(y), np.ascontiguousarray(w), phi, np.ascontiguousarray(nuis), nv, float(centre),
            va, vb, s2, float(prior_dof), dn, float(lam), first)
        lps.append(lp)
        finals.append((mass, kind, start, beta, cov, ssr, cnt))
    mixed, post_lam = mixed_log_density(np.array(lps))
    hazard = float(sum(p / lam for p, lam in zip(post_lam, hazards)))
    comps, wts = [], []
    flat_now = 0.0
    start_mass: dict = {}
    for p_lam, (mass, kind, start, beta, cov, ssr, cnt) in zip(post_lam, finals):
        for j in range(len(mass)):
            wt = p_lam * mass[j]
            flat_now += wt * (kind[j] == 1)
            start_mass[int(start[j])] = start_mass.get(int(start[j]), 0.0) + wt
            if wt < 1e-3:
                continue
            dof = prior_dof + cnt[j]
            scale2 = (prior_dof * s2 + ssr[j]) / dof
            # state in (a at the segment's start, b): the level now is a + b (phi_now - phi_s)
            dphi = phi[-1] - phi[start[j]]
            t = np.array([[1.0, dphi], [0.0, 1.0]])
            c2 = t @ cov[j][:2, :2] @ t.T * scale2
            comps.append(SegmentFit(beta=t @ beta[j][:2], cov=c2, dof=float(dof), sd=math.sqrt(scale2),
                                    kind="flat" if kind[j] == 1 else "sloped", start_n=float(n[start[j]]),
                                    n_now=float(n[-1]), scale_ops=scale_ops, hazard=hazard, slope_var=vb * s2))
            wts.append(wt)
    order = np.argsort(wts)[::-1][:MAX_SEGMENTS]
    wts = np.array(wts)[order] / np.sum(np.array(wts)[order])
    comps = [replace(comps[i], sim_draws=nd) for i, nd in zip(order, share_draws(wts))]
    # the most probable start of the current segment, and the level step there
    s_best = max(start_mass, key=start_mass.get)
    step = step_sd = None
    last = None
    if s_best > 0:
        last = s_best + cut
        step, step_sd = level_step(n, y, w, s_best, prior_sd)
    lp_full = np.concatenate([np.full(cut, -np.inf), mixed])
    return ChangePointFamily(comps, wts, lp_full, hazard, {float(k): round(float(v), 4) for k, v in
                                                           zip(hazards, post_lam)},
                             last, step, step_sd, float(flat_now))
