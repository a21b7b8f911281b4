"""Stage 3 — the capture as the unit of evidence (issue 36): each hypothesis is scored by how
well it predicts a capture it was not fitted on.

Why. Five captures hold ~25,000 samples. When no catalogued law is exactly the true shape, a
misfit of a tenth of the noise between two wrong shapes is worth a Δχ² of ~250 over the samples,
and whichever wrong family absorbs it best "wins" at 1.00; coloured vibration and a sensor zero
inflate the same sum. An effect is a repeatable signature of the breaker; what varies from
capture to capture (conditions, vibration, the sensor's zero) is what tells it from a flexible
shape fitting noise. So the unit of evidence is the capture.

The linear-Gaussian model, per capture i (everything whitened, then pre-whitened):

* the nuisance tangent N_i: the capture's reduced state and τ (``windows.linearise``), the
  sensor's zero and gain, and for a closing the cam's keying (``windows.sensor_columns``);
  projected out of everything below (P⊥_i), i.e. each capture keeps its own nuisance in every
  hypothesis and every fold;
* noise: pre-whitened by the in-motion residual's AR(``AR_ORDER``) filter (Yule–Walker on what a
  per-capture spline of 0.5 ms knots leaves, i.e. the vibration and the sensor noise, not the
  smooth gap), scaled to its innovation variance: a filter, not a variance factor;
* a hypothesis H is a basis X_i^H whose coefficients β are shared by the captures (one defect of
  one breaker): each catalogued family is the low-dimensional subspace (SVD) of the signatures it
  adds through capture i's own physics at the family's deterministic shapes (``hypotheses
  .family_starts``), pairs are the union of two, and ``outside_catalogue`` is a shared cubic
  B-spline in the capture's normalised motion time (knots every ``KNOT_S``), alone or beside the
  best family;
* β ~ N(0, g·(XᵀX)⁻¹) with g = n (Zellner's unit-information prior), so every fold's posterior and
  predictive density are closed form.

Leave one capture out (LOO): fit β on the others, score the held-out capture's projected
residual by its predictive density N(X_j m, I + X_j V X_jᵀ) (Woodbury: with M = Σ XᵀX + Λ over
all captures, C⁻¹ = I − X_j M⁻¹ X_jᵀ and ln det C = ln det M − ln det(M − X_jᵀX_j)). A shape that
only soaks up misfit, or vibration that does not repeat, does not predict the held-out capture.
With one capture, the units are its ~2 ms stretches (``UNIT_S``), and the result says one capture
cannot decide between close rivals.

What this stage leaves is every hypothesis's features (``features.collect``: its elpd per unit,
its held-out share of the gap per capture, where in the motion it acts), not probabilities: the
learnt scorer (``scorer``) turns those into probabilities (issue 48; the pseudo-BMA+ softmax of
these sums, its Occam term and prior, which stated wrong answers at ≥ 0.99, are gone). The Occam
factor below only chooses which outside-the-catalogue alternative and which families are refitted.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from ..mechanics.effects import REFERENCE_STRENGTHS as REALISTIC
from .hypotheses import family_starts, signature
from .linearised import exact_fit, member_from_pair
from .features import collect, loo_lpd  # noqa: F401 (loo_lpd: the scoring core, re-exported)
from .parallel import pmap
from .noise import AR_ORDER, NOISE_KNOT_S, _orth, _prewhiten, spline_basis, yule_walker  # noqa: F401 (re-exported)
from .windows import Windows

KNOT_S = 2.0e-3        # [s] knots of the shared discrepancy: below ~250 Hz, under the struck modes of the linkage
UNIT_S = 2.0e-3        # [s] the units of a single capture
FAMILY_DIM = 3         # a family's subspace: this many directions for every family, so that
                       # the Occam factor never chooses between families, only the data do
SHAPE_POINTS = 10      # quasi-random shapes per family (Halton, fixed) beside its starts
PAIR_TOP = 3           # pairs of the best singles
EXACT_TOP = 3          # effect hypotheses refitted jointly (and scored at their own profile)
REFINE_TOP = 3         # families refitted nonlinearly about their best point
REFINE_NFEV = 12       # least-squares evaluations of that refit
SEGMENT = 8            # columns of a local discrepancy (~16 ms), every half of it
SEED = 36
RESTART_ALL = False    # every exact single restarted (the former method) or the leading one only


@dataclass
class Scores:
    """Per hypothesis: its basis dimension, per-unit LOO log predictive densities (relative to
    ``none``), elpd (their sum); the units' kind and count; ``features`` of every hypothesis and
    of the group; ``weights``: the scorer's probabilities, set by ``diagnose``."""

    names: list
    dim: dict
    lpd: dict                 # name -> array over units (lpd_H − lpd_none)
    elpd: dict
    prior: dict
    weights: dict
    units: str                # "captures" or "stretches of one capture"
    n_units: int
    noise_ar: list = field(default_factory=list)   # per capture (AR coefficients, innovation sd)
    linear_shrink: dict = field(default_factory=dict)
    refined: dict = field(default_factory=dict)    # family -> its nonlinear HypothesisFit
    exact: dict = field(default_factory=dict)      # hypothesis -> its exact joint refit
    features: dict = field(default_factory=dict)   # ``features.collect``: every hypothesis's and the group's

    def ranked(self):
        return sorted(self.weights.items(), key=lambda kv: -kv[1])

    def se_difference(self, a: str, b: str) -> float:
        """Standard error of elpd_a − elpd_b from the spread over the units (Vehtari et al. 2017)."""
        d = self.lpd[a] - self.lpd[b]
        return float(np.sqrt(d.size * np.var(d, ddof=1))) if d.size > 1 else float("inf")


@dataclass
class _Cap:
    r: np.ndarray          # projected, pre-whitened residual
    cols: dict             # name -> projected, pre-whitened columns
    t_rel: np.ndarray      # normalised motion time of the rows [s]
    ar: tuple
    f: object = None       # the capture's noise filter
    Qw: np.ndarray = None  # orthonormal basis of its filtered nuisance tangent

    def columns(self, sigs) -> np.ndarray:
        """Whitened signatures (n × k) filtered and with the nuisance projected out."""
        X = self.f(np.column_stack(sigs))
        return X - self.Qw @ (self.Qw.T @ X)


def motion_time(cw, breaker, operation):
    """Rows' time since the capture's onset, normalised to the group's time scale later [s]; and
    the capture's time to 90 % of its reduced curve's stroke (its speed) [s]."""
    from .data import model_curve

    tau = float(cw.x[-1])
    tm = cw.data.t - tau
    m = model_curve(cw.x, cw.data, breaker, operation)
    span = float(np.max(m) - np.min(m)) if m.size else 0.0
    base = float(m[0])
    k = np.nonzero(np.abs(m - base) >= 0.9 * span)[0] if span > 0 else []
    t90 = float(tm[k[0]]) if len(k) and tm[k[0]] > 0 else float(tm[-1])
    return tm, max(t90, 1e-3)


def family_points(effect: str) -> list:
    """The family's parameter points whose signatures span its subspace: its deterministic
    starts (``hypotheses.family_starts``) and SHAPE_POINTS shapes spread over its bounds
    (a scrambled Halton sequence, fixed seed) at 0.6 and 1.5 × the realistic strength."""
    from scipy.stats import qmc

    from ..mechanics.effects import SIGNED, shape_bounds
    from .hypotheses import strength_bounds

    pts = list(family_starts(effect))
    lo, hi = (np.asarray(b, float) for b in shape_bounds(effect))
    if lo.size:
        u = qmc.Halton(d=lo.size, scramble=True, seed=SEED).random(SHAPE_POINTS)
        shapes = lo + u * (hi - lo)
    else:
        shapes = np.zeros((SHAPE_POINTS, 0))
    s_lo, s_hi = strength_bounds(effect)
    for k, sh in enumerate(shapes):
        if effect == "rod_elasticity":
            st = float(np.exp(np.log(s_lo) + (k + 0.5) / SHAPE_POINTS * (np.log(s_hi) - np.log(s_lo))))
        else:
            st = (0.6 if k % 2 else 1.5) * REALISTIC[effect] * (-1.0 if effect in SIGNED and k % 4 >= 2 else 1.0)
        pts.append(np.concatenate([[st], sh]))
    return pts


# --- the bases -------------------------------------------------------------------------------

def capture_bases(windows: Windows, catalogue, filters=None) -> list:
    """Per capture: pre-whitened, projected residual, family signatures and discrepancy rows
    (``filters``: the noise filters to use, e.g. those of the reduced fit's residual, so that
    densities at another nuisance profile compare)."""
    op, br = windows.operation, windows.breaker
    times = pmap(lambda cw: motion_time(cw, br, op), windows.captures)
    t_ref = float(np.median([t90 for _, t90 in times]))
    lo = min(float(tm[0]) * t_ref / t90 for tm, t90 in times)
    hi = max(float(tm[-1]) * t_ref / t90 for tm, t90 in times) + 1e-9

    def one(i):
        cw, (tm, t90) = windows.captures[i], times[i]
        f, ar = _prewhiten(cw) if filters is None else filters[i]
        Qw = _orth(f(cw.Q))
        P = (lambda X, Qw=Qw: X - Qw @ (Qw.T @ X))
        cols = {}
        for e in catalogue:
            sigs = []
            for z in family_points(e):
                s = signature(cw, op, br, [(e, float(z[0]), np.asarray(z[1:], float))])
                ok = bool(np.all(np.abs(s) < 1e3) and np.any(s != 0))
                sigs.append(s if ok else np.full(s.shape, np.nan))
            cols[e] = P(f(np.column_stack(sigs))) if sigs else np.zeros((cw.r.size, 0))
        u = tm * t_ref / t90
        D = spline_basis(u, lo, hi, KNOT_S) * cw.data.weight[:, None]
        cols["__disc__"] = P(f(D))
        return _Cap(P(f(cw.r[:, None]))[:, 0], cols, u, ar, f, Qw)

    return pmap(one, range(len(windows.captures)))


def point_gain(caps, effect: str) -> float:
    """Half the χ² the family's best sampled point removes with a free amplitude [nats]."""
    best = 0.0
    for k in range(caps[0].raw[effect].shape[1]):
        xs = [c.raw[effect][:, k] for c in caps]
        if not all(np.all(np.isfinite(x)) for x in xs):
            continue
        num = sum(float(x @ c.r) for x, c in zip(xs, caps))
        den = sum(float(x @ x) for x in xs)
        if den > 0:
            best = max(best, 0.5 * num * num / den)
    return best


def best_point(caps, effect: str):
    """The family's sampled point whose signature, alone and scaled, best fits the captures'
    residual (the start of its local refinement)."""
    pts = family_points(effect)
    best, arg = -np.inf, 0
    for k in range(len(pts)):
        num = den = 0.0
        ok = True
        for c in caps:
            x = c.raw[effect][:, k]
            if not np.all(np.isfinite(x)):
                ok = False
                break
            num += float(x @ c.r)
            den += float(x @ x)
        if ok and den > 0 and num / np.sqrt(den) > best:
            best, arg = num / np.sqrt(den), k
    z = np.array(pts[arg], float)
    c = sum(float(cc.raw[effect][:, arg] @ cc.r) for cc in caps) / max(
        sum(float(cc.raw[effect][:, arg] @ cc.raw[effect][:, arg]) for cc in caps), 1e-300)
    z[0] *= float(np.clip(c, 0.2, 5.0)) if effect != "rod_elasticity" else 1.0
    return z


def refine_family(windows, caps, effect: str):
    """The family's local subspace about its joint nonlinear fit (shared strength and shape,
    each capture's state profiled, from ``best_point``): the SVD of its signatures at the fitted
    point and at points moved along each parameter. Returns the fit."""
    from .hypotheses import fit_hypothesis, strength_bounds

    z0 = best_point(caps, effect)
    lo_s, hi_s = strength_bounds(effect)
    z0[0] = float(np.clip(z0[0], lo_s, hi_s))
    h = fit_hypothesis(windows, (effect,), [z0], refine_nfev=REFINE_NFEV)
    local_subspace(windows, caps, effect, *h.phi[effect])
    return h


def local_subspace(windows, caps, effect: str, st: float, sh):
    """The family's subspace about (strength, shape): SVD of its signatures there and at points
    moved along each parameter (10 % of its range; the strength ×1.3)."""
    from ..mechanics.effects import shape_bounds

    op, br = windows.operation, windows.breaker
    sh = np.asarray(sh, float)
    lo, hi = (np.asarray(b, float) for b in shape_bounds(effect))
    pts = [(st, sh), (st * 1.3, sh)]
    for j in range(sh.size):
        d = 0.1 * (hi[j] - lo[j])
        for sg in (1.0, -1.0):
            v = sh.copy()
            v[j] = np.clip(v[j] + sg * d, lo[j], hi[j])
            pts.append((st, v))

    def one(item):
        c, cw = item
        sigs = [signature(cw, op, br, [(effect, float(a), np.asarray(b, float))]) for a, b in pts]
        c.cols[effect] = c.columns([np.where(np.abs(x) < 1e3, x, 0.0) for x in sigs])

    pmap(one, list(zip(caps, windows.captures)))
    family_subspace(caps, effect)


def outside(caps, bases, mean_rows, shift=0.0):
    """The best "outside the catalogue" alternative: the shared discrepancy everywhere or in one
    stretch (SEGMENT columns, every half of it), alone or beside each hypothesis of ``bases``
    (tuples of families), by LOO elpd less its Occam factor. Returns (lpd, value, k, count)."""
    K = caps[0].cols["__disc__"].shape[1]
    spans = [np.arange(K)] + [np.arange(a, min(a + SEGMENT, K)) for a in range(0, max(K - SEGMENT, 0) + 1, SEGMENT // 2)]
    best = (None, -np.inf, 0)
    n = 0
    for base in [()] + [tuple(b) if isinstance(b, tuple) else (b,) for b in bases]:
        for cols in spans:
            for c in caps:
                c.cols["__seg__"] = c.cols["__disc__"][:, cols]
            uu, _ = _units(caps)
            v = loo_lpd(uu, base + ("__seg__",)) + shift
            k = cols.size + sum(caps[0].cols[b].shape[1] for b in base)
            val = float(np.sum(v)) - occam(k, mean_rows)
            n += 1
            if val > best[1]:
                best = (v, val, k)
    return (*best, n)


def family_subspace(caps, name: str):
    """Reduce a family's columns to its shared subspace: SVD of the signatures stacked over the
    captures (each column normalised), keeping ≤ MAX_DIM directions above DIM_TOL."""
    S = np.vstack([c.cols[name] for c in caps])
    if S.shape[1] == 0:
        return
    valid = np.all(np.isfinite(S), axis=0)        # a shape the integrator failed on, on any capture
    S = np.where(valid[None, :], S, 0.0)
    nrm = np.linalg.norm(S, axis=0)
    keep = valid & (nrm > 0)
    if not keep.any():
        for c in caps:
            c.cols[name] = c.cols[name][:, :0]
        return
    Sn = S[:, keep] / nrm[keep]
    # the right singular vectors and values from the (small) Gram matrix: same subspace, k × k work
    lam, W = np.linalg.eigh(Sn.T @ Sn)
    order = np.argsort(lam)[::-1]
    s = np.sqrt(np.maximum(lam[order], 0.0))
    d = int(min(FAMILY_DIM, np.sum(s >= 1e-6 * s[0]))) if s.size and s[0] > 0 else 0
    V = W[:, order[:d]] / s[:d]
    for c in caps:
        c.cols[name] = (np.nan_to_num(c.cols[name][:, keep]) / nrm[keep]) @ V


def drop_empty_discrepancy(caps):
    """Discrepancy columns no capture's rows touch carry nothing: dropped."""
    S = np.vstack([c.cols["__disc__"] for c in caps])
    keep = np.linalg.norm(S, axis=0) > 1e-9 * max(float(np.linalg.norm(S)), 1e-300)
    for c in caps:
        c.cols["__disc__"] = c.cols["__disc__"][:, keep]


# --- scoring ---------------------------------------------------------------------------------

def _units(caps):
    """The units of evidence: the captures, or with one capture its ~UNIT_S stretches."""
    if len(caps) > 1:
        return [(c.r, c.cols) for c in caps], "captures"
    c = caps[0]
    edges = np.arange(float(c.t_rel[0]), float(c.t_rel[-1]) + UNIT_S, UNIT_S)
    idx = np.clip(np.searchsorted(edges, c.t_rel, side="right") - 1, 0, None)
    units = []
    for k in np.unique(idx):
        sel = idx == k
        units.append((c.r[sel], {n: X[sel] for n, X in c.cols.items()}))
    return units, "stretches of one capture"


def occam(k: int, rows: float) -> float:
    """The Occam factor [nats] of k shared coefficients: ½ k ln(rows of one unit), Schwarz's,
    counted in one unit's blocks: a shape shared by the captures must pay for itself in the
    evidence of a single capture (LOO alone charges it almost nothing, so every useless family
    would keep a share near its prior and a healthy group could never be stated ``none``)."""
    return 0.5 * k * float(np.log(max(rows, 2.0)))


def score(windows: Windows, catalogue) -> Scores:
    caps = capture_bases(windows, catalogue)
    for c in caps:
        c.raw = {e: c.cols[e].copy() for e in catalogue}
    for e in catalogue:
        family_subspace(caps, e)
    drop_empty_discrepancy(caps)
    units, kind = _units(caps)
    mean_rows = float(np.mean([r.size for r, _ in units]))
    hyps = {"none": ()}
    lpd = {"none": np.zeros(len(units))}
    for e in catalogue:
        if caps[0].cols[e].shape[1]:
            hyps[e] = (e,)
            lpd[e] = loo_lpd(units, (e,))
    singles = sorted((e for e in hyps if e != "none"), key=lambda e: -float(np.sum(lpd[e])))
    # the leading families refitted nonlinearly and their subspaces taken about the fit: a
    # sampled subspace of three directions cannot hold a ringing of any frequency or a buffer of
    # any law, a local one can
    refined = {}
    gain = {e: point_gain(caps, e) for e in singles}
    lead = sorted(singles, key=lambda e: -gain[e])[:REFINE_TOP]
    lead += [e for e in singles[:1] if e not in lead]
    for e in lead:
        if gain[e] > occam(FAMILY_DIM, mean_rows) or np.sum(lpd[e]) > 0:
            refined[e] = refine_family(windows, caps, e)
            lpd[e] = loo_lpd(_units(caps)[0], (e,))
    units, kind = _units(caps)
    singles = sorted((e for e in hyps if e != "none"), key=lambda e: -float(np.sum(lpd[e])))
    for a, b in combinations(singles[:PAIR_TOP], 2):
        pair = tuple(sorted((a, b)))
        name = "+".join(pair)
        hyps[name] = pair
        lpd[name] = loo_lpd(units, pair)
    # outside the catalogue: the shared discrepancy, everywhere or in one stretch, alone or beside
    # the best family; the best of these alternatives, each paying its own Occam factor and
    # together ln(their number) for the choice
    best_out, best_val, best_k, n_alt = outside(caps, singles[:1], mean_rows)
    # each effect hypothesis is scored at its own nuisance profile: the leading one is refitted
    # exactly (shared effect, every capture's state and τ), the captures linearised again at the
    # states it found, and it and the discrepancy scored there (a strong effect moves the states
    # beyond the reach of the reduced fit's tangent, and the discrepancy would otherwise win on
    # the linearisation error alone)
    effect_hyps = [k for k in hyps if k != "none"]
    dims = {k: int(sum(caps[0].cols[n].shape[1] for n in v)) for k, v in hyps.items()}
    pen = {k: float(np.sum(lpd[k])) - occam(dims[k], mean_rows) for k in effect_hyps}
    cand = [k for k in sorted(effect_hyps, key=lambda k: -pen[k])[:EXACT_TOP] if pen[k] > 0]
    for k in list(cand):          # a pair is compared with its own members at their own profiles
        cand += [e for e in hyps[k] if len(hyps[k]) == 2 and e not in cand and e in hyps]
    exact = {}
    # the restarts against a multimodal shape objective (from the design state, from every
    # start) for the leading single only: on a realistic sensor every single stays above the
    # white floor that triggers them, and they were ~60 % of a single's refit (issue 54 item 1)
    singles_c = [k for k in cand if len(hyps[k]) == 1]
    lead_single = max(singles_c, key=lambda k: pen.get(k, -np.inf)) if singles_c else None
    cand.sort(key=lambda k: -len(hyps[k]))      # pairs first: their members then start from them too
    for k in cand:
        h = exact_fit(windows, hyps[k], refined, restarts=RESTART_ALL or k == lead_single)
        if len(hyps[k]) == 1:
            # a pair must not win on convergence alone: the member is also refitted alone from the
            # states and parameters of the best pair holding it (the one it must be compared
            # with; the others' starts cost a refit each, issue 54 item 1), and the better fit kept
            e = hyps[k][0]
            pairs = [ph for pk, ph in exact.items() if e in hyps[pk] and len(hyps[pk]) == 2]
            if pairs:
                alt = member_from_pair(windows, e, min(pairs, key=lambda ph: ph.chi2))
                if alt.chi2 < h.chi2:
                    h = alt
        exact[k] = h
        w2 = Windows(windows.operation, windows.breaker, h.captures)
        caps2 = capture_bases(w2, (), filters=[(c.f, c.ar) for c in caps])
        for e in hyps[k]:
            local_subspace(w2, caps2, e, *h.phi[e])
        drop_empty_discrepancy(caps2)
        u2, _ = _units(caps2)
        # densities relative to ``none`` at the reduced fit's profile (the same filter, rows)
        shift = np.array([-0.5 * (float(r2 @ r2) - float(r1 @ r1)) for (r2, _), (r1, _) in zip(u2, units)])
        v2 = loo_lpd(u2, hyps[k]) + shift
        if np.sum(v2) > np.sum(lpd[k]):
            lpd[k] = v2
        o2 = outside(caps2, [hyps[k]], mean_rows, shift)
        if o2[1] > best_val:
            best_out, best_val, best_k = o2[:3]
        n_alt += o2[3]
    hyps["outside_catalogue"] = ("__disc__",)
    lpd["outside_catalogue"] = best_out
    dims["outside_catalogue"] = best_k
    # the probabilities are the learnt scorer's (``scorer``), from every hypothesis's features:
    # no prior, Occam term or softmax of these sums here (issue 48 item 5)
    feats = collect(caps, units, lpd, dims, hyps, singles)
    return Scores(list(hyps), dims, lpd, {k: float(np.sum(v)) for k, v in lpd.items()}, {}, {}, kind,
                  len(units), [c.ar for c in caps], {}, refined, exact, feats)
