"""Stage 2 — fits per hypothesis, jointly over the N captures of one breaker.

A hypothesis is a set of catalogued effects (none, one, or a pair). Each capture keeps its own
state (AO…EO or AC…CC, and τ); the effects' strengths and shape parameters are shared by all
captures (one physical defect). Because each effect acts through the physics on each capture's
own state, the invariants come for free: a sensor error stays the same function of angle, an
orifice force follows each capture's speed², a viscous one its speed, the rod its frequency.

The state is profiled out linearly: with r_i the whitened reduced residual and J_i the whitened
state Jacobian of capture i at its reduced fit, the effect's whitened signature
s_i(φ) = (model(x_i; φ) − model(x_i; none))·w_i is compared on what the state cannot absorb,

    χ²(φ) = Σ_i ‖P⊥_i (r_i − s_i(φ))‖²,   P⊥_i = I − Q_i Q_iᵀ  (Q_i: basis of J_i),

which is the Gauss–Newton profile of the joint likelihood over the states (exact for the small
state changes an effect of realistic size causes). φ is fitted by bounded least squares from the
family's deterministic starts. ``outside`` adds to the best catalogued hypothesis the
discrepancy term (``discrepancy``), the alternative "something the catalogue does not describe".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from scipy.optimize import least_squares

from ..mechanics.effects import EFFECT_NAMES, OPERATIONS, PHYSICAL_UPPER as FIT_UPPER, REFERENCE_STRENGTHS as REALISTIC
from ..mechanics.effects import SHAPES, SIGNED, shape_bounds, shape_defaults
from .data import JAC_DT_S, curve_step, design_state, fd_steps, model_curve, state_bounds
from .parallel import pmap
from .windows import Windows, linearise, tau_span

SCREEN_NFEV = 8     # evaluations per deterministic start
REFINE_NFEV = 12    # evaluations of the best start (the exact refit does the rest)
RELIN = 0           # re-linearisations of a promising hypothesis (superseded by the exact refit)
EXACT_NFEV = 30     # evaluations of the exact joint refit
EXACT_TOP = 4       # singles refitted exactly: the best by the linearised BIC
RELIN_NFEV = 12     # evaluations of each re-linearised refit
PAIR_TOP = 3        # pairs are formed from the best singles (ΔBIC < 0) ...
RESCREEN_TOP = 2    # singles screened again from every start after their exact refit

# Deterministic extra starts of each family's shape (besides the prototype's defaults): forms far
# from the default that a local fit from the default would not reach (signs, exponents, sides).
ALT_SHAPES = {
    "linkage_kinematics": [(0.4, 0.0), (-0.4, 0.0), (0.0, 0.8)],
    "orifice_buffer": [(1.4, 0.25, 0.01)],
    "puffer_gas": [(1.2, 2.2, 40.0)],
    "rod_elasticity": [(0.08, 1.0)],
    "stribeck_friction": [(1.0, 1.2)],
    "viscous_friction": [(0.6,), (-0.6,)],
    "spring_nonlinearity": [(3.0, 0.0), (2.0, 1.0)],
    "sensor_nonlinearity": [(2.0, 0.0), (3.0, 0.0)],
    "cam_friction": [(0.7,), (-0.7,)],
    "contact_wipe": [(0.85, 0.2), (0.6, 0.8)],
}
ROD_STARTS = (0.15, 0.3, 1.0, 2.2)   # ε = (150 Hz / f)²: 100–390 Hz; the ringing is multimodal in f


def strength_bounds(effect: str):
    """[lo, hi] of a fitted strength: [0, FIT_UPPER], ±FIT_UPPER for signed families."""
    if effect == "rod_elasticity":
        return 0.09, 9.0
    return (-FIT_UPPER[effect] if effect in SIGNED else 0.0), FIT_UPPER[effect]


def n_params(effect: str) -> int:
    return 1 + len(SHAPES[effect])


@dataclass
class HypothesisFit:
    """One hypothesis fitted jointly.

    effects : tuple of effect names (() = none; "outside" adds the generic correction);
    phi : {effect: (strength, shape array)}; k : free parameters beyond the reduced model;
    chi2 : Σ‖P⊥(r − s)‖² over captures; chi2_per : per capture; signatures : per capture s_i.
    """

    effects: tuple
    phi: dict
    k: int
    chi2: float
    chi2_per: list
    signatures: list = field(repr=False, default_factory=list)
    outside: bool = False
    captures: list = field(repr=False, default_factory=list)   # CaptureWindows linearised at its states
    resid: list | None = field(repr=False, default=None)        # per capture whitened residual (outside)
    discrepancy: object = field(repr=False, default=None)       # discrepancy.Discrepancy (outside)
    base_k: int = 0                                             # k of the catalogued part (outside)

    def residuals(self):
        """Per capture whitened residual left by the hypothesis (states profiled out)."""
        if self.resid is not None:
            return self.resid
        return [cw.project_out(cw.r - s) for cw, s in zip(self.captures, self.signatures)]

    @property
    def name(self) -> str:
        if self.outside:
            return "outside_catalogue"
        return "+".join(self.effects) if self.effects else "none"

    def as_effects(self):
        return [(e, float(self.phi[e][0]), np.asarray(self.phi[e][1], float)) for e in self.effects]


@dataclass
class Fits:
    """Stage 2 result: every hypothesis fitted, by name."""

    windows: Windows
    hypotheses: dict

    def best_catalogued(self, n_total: int):
        cat = [h for h in self.hypotheses.values() if not h.outside]
        return min(cat, key=lambda h: h.chi2 + h.k * np.log(n_total))


def signature(cw, operation, breaker, effects, x=None, sensor_side=False):
    """Whitened change of the model curve of capture ``cw`` caused by ``effects``."""
    x = cw.x if x is None else x
    m0 = cw.data.y - cw.r / cw.data.weight
    m = model_curve(x, cw.data, breaker, operation, effects, sensor_side=sensor_side)
    s = (m - m0) * cw.data.weight
    return np.where(np.isfinite(s), s, 1e3)


def _layout(effects):
    lo, hi, scale, sl = [], [], [], {}
    for e in effects:
        s_lo, s_hi = strength_bounds(e)
        sh_lo, sh_hi = shape_bounds(e)
        i0 = len(lo)
        lo += [s_lo, *sh_lo]
        hi += [s_hi, *sh_hi]
        scale += [REALISTIC[e], *((sh_hi - sh_lo) * 0.25)]
        sl[e] = slice(i0, i0 + 1 + len(sh_lo))
    return np.array(lo), np.array(hi), np.array(scale), sl


def _unpack(z, effects, sl):
    return [(e, float(z[sl[e]][0]), z[sl[e]][1:]) for e in effects]


def fit_hypothesis(windows: Windows, effects: tuple, starts, *, subset=None,
                   refine_nfev: int = REFINE_NFEV, relinearise: int = 0, caps=None) -> HypothesisFit:
    """Fit the shared parameters of ``effects`` from each start vector; the best one refined.
    ``relinearise``: that many times, move each capture's state to its profiled optimum under
    the fitted effect, linearise there again and refit (a strong effect shifts the state beyond
    the reach of the first linearisation)."""
    if caps is None:
        caps = windows.captures if subset is None else [windows.captures[i] for i in subset]
    op, br = windows.operation, windows.breaker
    lo, hi, scale, sl = _layout(effects)

    def fun(z):
        eff = _unpack(z, effects, sl)
        return np.concatenate(pmap(lambda cw: cw.project_out(cw.r - signature(cw, op, br, eff)), caps))

    def jac(z):
        # scipy's forward differences (diff_step 1e-4) of a smooth family's curves, each
        # capture's columns in one task
        steps = fd_steps(z, 1e-4, lo, hi)

        def one(cw):
            w = cw.data.weight
            mc = model_curve(cw.x, cw.data, br, op, _unpack(z, effects, sl))
            cols = []
            for j in range(z.size):
                zp = np.array(z, float)
                zp[j] += steps[j]
                d = (model_curve(cw.x, cw.data, br, op, _unpack(zp, effects, sl)) - mc) * w
                cols.append(-np.where(np.isfinite(d), d, 0.0) / steps[j])
            return cw.project_out(np.column_stack(cols))

        return np.vstack(pmap(one, caps))

    # a family that moves a kink keeps scipy's differences of the residual itself (its columns
    # need the curves' finer grid, ``linearised._effect_jac``)
    smooth = curve_step(op, [(e, 1.0, None) for e in effects]) == JAC_DT_S
    jac = jac if smooth else "2-point"
    fd = {} if smooth else {"diff_step": 1e-4}

    best = None
    for z0 in starts:
        z0 = np.clip(np.asarray(z0, float), lo, hi)
        res = least_squares(fun, z0, jac=jac, bounds=(lo, hi), x_scale=scale,
                            max_nfev=SCREEN_NFEV if len(starts) > 1 else refine_nfev, **fd)
        if best is None or res.cost < best.cost - 1e-9 * abs(best.cost):
            best = res
    if len(starts) > 1:
        best = least_squares(fun, best.x, jac=jac, bounds=(lo, hi), x_scale=scale, max_nfev=refine_nfev, **fd)
    eff = _unpack(best.x, effects, sl)
    sigs = pmap(lambda cw: signature(cw, op, br, eff), caps)
    per = [float(np.sum(cw.project_out(cw.r - s) ** 2)) for cw, s in zip(caps, sigs)]
    phi = {e: (s, np.array(sh, float)) for e, s, sh in eff}
    h = HypothesisFit(tuple(effects), phi, int(len(lo)), float(sum(per)), per, sigs, captures=list(caps))
    if relinearise > 0:
        moved = [linearise(cw.x + cw.state_step(cw.r - s), cw.data, br, op) for cw, s in zip(caps, sigs)]
        h2 = fit_hypothesis(windows, effects, [best.x], refine_nfev=RELIN_NFEV, relinearise=relinearise - 1,
                            caps=moved)
        if h2.chi2 < h.chi2:
            return h2
    return h


def refine_exact(windows: Windows, h: HypothesisFit, *, max_nfev: int = EXACT_NFEV) -> HypothesisFit:
    """The exact joint fit: shared effect parameters and every capture's own state and τ
    together, by bounded least squares on the whitened residuals of all captures (sparse
    Jacobian: a capture's rows depend on its own state and the shared parameters only), from the
    linearised solution. Returns the hypothesis re-linearised at the fitted states."""
    from scipy.sparse import lil_matrix

    op, br = windows.operation, windows.breaker
    caps = h.captures
    effects = h.effects
    lo_e, hi_e, sc_e, sl = _layout(effects)
    ke = lo_e.size
    p = caps[0].x.size
    x0 = [np.clip(cw.x + cw.state_step(cw.r - sg), *_state_bounds(cw.x, op)) for cw, sg in zip(caps, h.signatures)]
    z0 = np.concatenate([np.concatenate([np.concatenate([[h.phi[e][0]], h.phi[e][1]]) for e in effects])] + x0)
    lo = np.concatenate([lo_e] + [_state_bounds(cw.x, op)[0] for cw in caps])
    hi = np.concatenate([hi_e] + [_state_bounds(cw.x, op)[1] for cw in caps])
    scale = np.concatenate([sc_e] + [_state_scale(cw.x) for cw in caps])
    sizes = [cw.r.size for cw in caps]
    rows = np.cumsum([0] + sizes)
    sp = lil_matrix((rows[-1], z0.size), dtype=int)
    for i in range(len(caps)):
        sp[rows[i]:rows[i + 1], :ke] = 1
        sp[rows[i]:rows[i + 1], ke + i * p: ke + (i + 1) * p] = 1

    def fun(z):
        eff = _unpack(z[:ke], effects, sl)

        def one(i):
            cw = caps[i]
            x = z[ke + i * p: ke + (i + 1) * p]
            r = (cw.data.y - model_curve(x, cw.data, br, op, eff)) * cw.data.weight
            return np.where(np.isfinite(r), r, 1e3)

        return np.concatenate(pmap(one, range(len(caps))))

    z0 = np.clip(z0, lo, hi)
    res = least_squares(fun, z0, bounds=(lo, hi), x_scale=scale, max_nfev=max_nfev, diff_step=1e-5,
                        jac_sparsity=sp, tr_solver="lsmr")
    nb = rows[-1]
    if 2 * res.cost > nb + 5 * np.sqrt(2 * nb):
        # not at the noise floor: a strong effect can have pushed the reduced states far from
        # the truth (a contact wipe read as BC −40 %); also start from the breaker's design state
        xd = design_state(br, op)
        z1 = z0.copy()
        for i in range(len(caps)):
            z1[ke + i * p: ke + (i + 1) * p - 1] = xd
        res1 = least_squares(fun, np.clip(z1, lo, hi), bounds=(lo, hi), x_scale=scale, max_nfev=max_nfev,
                             diff_step=1e-5, jac_sparsity=sp, tr_solver="lsmr")
        if res1.cost < res.cost:
            res = res1
    eff = _unpack(res.x[:ke], effects, sl)
    return refit_if_better(h, effects, eff, [res.x[ke + i * p: ke + (i + 1) * p] for i in range(len(caps))],
                           caps, br, op)


def refit_if_better(h, effects, eff, states, caps, br, op):
    """The hypothesis relinearised at its refitted capture ``states`` with the effects ``eff``, or
    ``h`` itself when the refit does not lower its χ² (a refit never makes a hypothesis worse)."""
    new_caps, sigs, per = [], [], []
    for cw, x in zip(caps, states):
        nc = linearise(x, cw.data, br, op)
        sg = signature(nc, op, br, eff)
        new_caps.append(nc)
        sigs.append(sg)
        per.append(float(np.sum(nc.project_out(nc.r - sg) ** 2)))
    if sum(per) >= h.chi2:
        return h
    phi = {e: (st, np.array(sh, float)) for e, st, sh in eff}
    return HypothesisFit(effects, phi, h.k, float(sum(per)), per, sigs, captures=new_caps)


def _state_bounds(x, operation):
    return state_bounds(x, operation, tau_span(float(x[-1])))


def _state_scale(x):
    s = np.maximum(np.abs(np.asarray(x, float)), 1e-6)
    s[-1] = 1e-4
    return s


def family_starts(effect: str):
    """Deterministic start vectors [strength, shape…] of one family."""
    real = REALISTIC[effect]
    sh0 = shape_defaults(effect)
    shapes = [sh0] + [np.array(a, float) for a in ALT_SHAPES.get(effect, ())]
    signs = (1.0, -1.0) if effect in SIGNED else (1.0,)
    starts = [np.concatenate([[sg * 0.5 * real], sh]) for sh in shapes for sg in signs]
    if effect == "rod_elasticity":
        starts += [np.concatenate([[eps], sh0]) for eps in ROD_STARTS]
    return starts


def none_fit(windows: Windows) -> HypothesisFit:
    per = [float(np.sum(cw.project_out(cw.r) ** 2)) for cw in windows.captures]
    zeros = [np.zeros_like(cw.r) for cw in windows.captures]
    return HypothesisFit((), {}, 0, float(sum(per)), per, zeros, captures=list(windows.captures))


def outside_fit(windows: Windows, best: HypothesisFit) -> HypothesisFit:
    """``best`` plus the discrepancy term (``discrepancy``): its least-squares residual and χ²
    (every coefficient free: the noise scale's residual), its closed-form evidence in ``evidence``."""
    from .discrepancy import build

    disc = build(best, windows.breaker, windows.operation)
    res = disc.ls_residuals()
    per = [float(np.sum(e ** 2)) for e in res]
    return HypothesisFit(best.effects, best.phi, best.k + disc.k, float(sum(per)), per, best.signatures,
                         outside=True, captures=best.captures, resid=res, discrepancy=disc, base_k=best.k)


def fit_all(windows: Windows, catalogue) -> "Fits":
    """none, every single family, pairs of the leading singles, and outside."""
    n = windows.n
    hyps = {"none": none_fit(windows)}
    singles = []
    for e in catalogue:
        h = fit_hypothesis(windows, (e,), family_starts(e))
        hyps[h.name] = h
    ranked = sorted((hyps[e] for e in catalogue), key=lambda h: h.chi2 + h.k * np.log(n))
    for h in ranked[:EXACT_TOP]:
        if h.chi2 + h.k * np.log(n) < hyps["none"].chi2:
            hyps[h.name] = refine_exact(windows, h)
    # The shape objective is multimodal (a contact touch's fraction moves a kink): the best
    # singles still above the noise are screened again from every start at the states the exact
    # fit found, and refitted (A's wipe group: χ² 1587 -> 1063 on 1005 blocks, the truth's 1013)
    floor = n + 5.0 * np.sqrt(2.0 * n)
    for h in sorted((hyps[e] for e in catalogue), key=lambda h: h.chi2)[:RESCREEN_TOP]:
        if h.chi2 > floor:
            e = h.effects[0]
            hb = fit_hypothesis(windows, (e,), family_starts(e), caps=h.captures)
            if hb.chi2 < h.chi2:
                h2 = refine_exact(windows, hb)
                if h2.chi2 < h.chi2:
                    hyps[e] = h2
    singles = [hyps[e] for e in catalogue]
    lead = sorted((h for h in singles if h.chi2 + h.k * np.log(n) < hyps["none"].chi2),
                  key=lambda h: h.chi2 + h.k * np.log(n))[:PAIR_TOP]
    for a, b in combinations(lead, 2):
        pair = tuple(sorted((a.effects[0], b.effects[0])))
        z0 = np.concatenate([[hyps[pair[0]].phi[pair[0]][0]], hyps[pair[0]].phi[pair[0]][1],
                             [hyps[pair[1]].phi[pair[1]][0]], hyps[pair[1]].phi[pair[1]][1]])
        lead_caps = min((hyps[pair[0]], hyps[pair[1]]), key=lambda x: x.chi2).captures
        h = refine_exact(windows, fit_hypothesis(windows, pair, [z0], caps=lead_caps))
        hyps[h.name] = h
    # A pair can beat its singles only because its refit converged further, not because both
    # effects are there: each effect of the best pair is refitted alone from the pair's states
    # and parameters, so that the evidence compares converged fits
    pairs = [h for h in hyps.values() if len(h.effects) == 2]
    if pairs:
        bp = min(pairs, key=lambda h: h.chi2)
        for e in bp.effects:
            alone = fit_hypothesis(windows, (e,), [np.concatenate([[bp.phi[e][0]], bp.phi[e][1]])],
                                   caps=bp.captures)
            alone = refine_exact(windows, alone)
            if alone.chi2 < hyps[e].chi2:
                hyps[e] = alone
    fits = Fits(windows, hyps)
    best = fits.best_catalogued(n)
    hyps["outside_catalogue"] = outside_fit(windows, best)
    return fits


def catalogue_for(operation: str, effects=None):
    return [e for e in (effects or EFFECT_NAMES) if operation in OPERATIONS.get(e, ())]


def holdout(windows: Windows, h: HypothesisFit):
    """Leave one capture out: fit the shared parameters on the others, predict the left-out one
    (its state refitted). Per capture: the gap shrink on the left-out capture."""
    if len(windows.captures) < 2 or not h.effects:
        return None
    z = np.concatenate([np.concatenate([[h.phi[e][0]], h.phi[e][1]]) for e in h.effects])
    out = []
    for i, cw in enumerate(h.captures):
        others = [h.captures[j] for j in range(len(h.captures)) if j != i]
        hi = fit_hypothesis(windows, h.effects, [z], caps=others, refine_nfev=10)
        s = signature(cw, windows.operation, windows.breaker, hi.as_effects())
        before = float(np.sum(cw.project_out(cw.r) ** 2))
        after = float(np.sum(cw.project_out(cw.r - s) ** 2))
        out.append(_shrink(before, after, cw.r.size))
    return out


def _shrink(chi_before, chi_after, n):
    """1 − gap_after/gap_before with gap² ∝ χ² − n (the noise part removed)."""
    g0 = max(chi_before - n, 0.0)
    g1 = max(chi_after - n, 0.0)
    return 0.0 if g0 <= 0 else float(1.0 - np.sqrt(g1 / g0))
