"""The joint refit of a hypothesis by Gauss–Newton in linear algebra (issue 42 item 1).

One defect of one breaker: shared effect parameters φ (strength, shape) and each capture's own
state x_i (the reduced parameters and τ). With r_i the whitened residual of capture i at
(x_i, φ), J_i = ∂m/∂x_i·w its state Jacobian and G_i = ∂m/∂φ·w its effect Jacobian, one
Gauss–Newton step minimises Σ_i ‖r_i − J_i δx_i − G_i δφ‖². Each capture's δx_i is eliminated
in closed form (its own state sees only its own rows: the Schur complement), so the shared step
solves a ke × ke system,

    (Σ_i G_iᵀ P⊥_i G_i + λ D) δφ = Σ_i G_iᵀ P⊥_i r_i,   P⊥_i = I − J_i J_i⁺,
    δx_i = J_i⁺ (r_i − G_i δφ),

with Levenberg–Marquardt damping λ (D the diagonal of the left side) and the steps clipped to
the physical bounds. A step costs 1 + p + ke model evaluations per capture (p state and τ
columns, ke effect columns): for 10 captures and a 4-parameter effect ~110 evaluations of
~2 ms, against the ~10⁴ of a trust-region refit with finite-difference Jacobians over all
captures. ``holdout_shrink`` reuses the same Jacobians: each capture predicted from the other
captures' linearised fit, with no further refit.
"""

from __future__ import annotations

import numpy as np

from .data import curve_step, model_curve, state_columns
from .parallel import pmap
from .hypotheses import (
    REFINE_NFEV,
    Fits,
    HypothesisFit,
    _layout,
    _shrink,
    _state_bounds,
    _unpack,
    family_starts,
    fit_hypothesis,
    none_fit,
    outside_fit,
    refine_exact,
    refit_if_better,
    signature,
)

FD_REL = 1e-3     # finite-difference step of an effect parameter, relative to its scale
LM_LAMBDA = 1e-3  # initial Levenberg–Marquardt damping (relative to the diagonal)
STEPS = (1.0, 0.5, 0.25, 0.1, 0.03)   # the share of the Gauss–Newton step tried, in turn
REUSE_J = False   # the first step with the linearisation's state Jacobian (cheaper; measured: it changes answers)


def _residual(cw, x, op, br, eff):
    r = (cw.data.y - model_curve(x, cw.data, br, op, eff)) * cw.data.weight
    return np.where(np.isfinite(r), r, 1e3)


def _state_jac(cw, x, op, br, eff, m0=None):
    """The state's whitened columns at ``x`` under ``eff``, on the Jacobians' grid
    (``data.state_columns``)."""
    return state_columns(x, cw.data, br, op, eff)


def _effect_jac(cw, x, op, br, z, unpack, scale, m0, lo, hi):
    """Whitened finite-difference columns of the shared effect parameters ``z`` at state ``x``
    (``m0``: the curve there). On the curve's own grid (``data.curve_step``): a family whose
    parameters move a kink (the buffer's engagement, a friction's breakaway) changes the
    discretisation error with them, so its columns need the finer step; a smooth family's
    curve is on the Jacobians' grid already."""
    w = cw.data.weight
    dt = curve_step(op, unpack(z))
    cols = []
    for j in range(z.size):
        h = FD_REL * scale[j]
        zp = z.copy()
        if zp[j] + h > hi[j]:
            h = -h
        zp[j] += h
        cols.append((model_curve(x, cw.data, br, op, unpack(zp), dt_max=dt) - m0) * w / h)
    G = np.column_stack(cols)
    return np.where(np.isfinite(G), G, 0.0)


def _evaluate(cw, x, op, br, eff):
    """Capture ``cw`` at state ``x`` under ``eff``: the raw whitened residual, the sensor's
    nuisance columns (zero, gain, a closing's cam keying: ``windows.sensor_columns``) and the
    residual with them profiled out (their least-squares part removed: they are linear)."""
    from .windows import sensor_columns

    r = _residual(cw, x, op, br, eff)
    m = cw.data.y - r / cw.data.weight
    S = sensor_columns(x, cw.data, br, op, m)
    c = np.linalg.lstsq(S, r, rcond=None)[0]
    return r, S, r - S @ c


def gauss_newton(windows, effects: tuple, z0, caps, *, iters: int = 3):
    """Joint Gauss–Newton refit of ``effects`` (shared vector z0 = [strength, shape…] per effect)
    and every capture's state (from the states of ``caps``), the sensor's zero, gain and keying
    profiled out of every capture. Returns (z, states, the profiled residuals, the last
    Jacobians (J_i, G_i))."""

    op, br = windows.operation, windows.breaker
    lo, hi, scale, sl = _layout(effects)
    unpack = lambda z: _unpack(z, effects, sl)
    z = np.clip(np.asarray(z0, float), lo, hi)
    xs = [np.asarray(cw.x, float).copy() for cw in caps]
    bounds = [_state_bounds(cw.x, op) for cw in caps]
    ev = pmap(lambda cx: _evaluate(cx[0], cx[1], op, br, unpack(z)), list(zip(caps, xs)))
    cost = sum(float(e[2] @ e[2]) for e in ev)
    lam = LM_LAMBDA
    jac = None
    for it in range(max(iters, 0)):
        def jacobians(item, it=it, z=z):
            cw, x, (r, S, _) = item
            m0 = cw.data.y - r / cw.data.weight
            J = cw.J if REUSE_J and it == 0 and cw.J.shape[1] == x.size else _state_jac(cw, x, op, br, unpack(z), m0)
            return J, _effect_jac(cw, x, op, br, z, unpack, scale, m0, lo, hi), np.column_stack([J, S])

        Js, Gs, Ns = (list(v) for v in zip(*pmap(jacobians, list(zip(caps, xs, ev)))))
        jac = (Js, Gs)
        A = np.zeros((z.size, z.size))
        b = np.zeros(z.size)
        pinv = []
        for N, G, (r, _, _) in zip(Ns, Gs, ev):
            Np = np.linalg.pinv(N, rcond=1e-10)
            pinv.append(Np)
            PG = G - N @ (Np @ G)
            A += G.T @ PG
            b += PG.T @ r
        improved = False
        for alpha in STEPS:
            # Levenberg–Marquardt on the shared step and a backtracking of the whole step (the
            # states' too: the model is not smooth at a cam's or a buffer's kink, where the
            # linear state step overshoots)
            D = np.diag(np.maximum(np.diag(A), 1e-12))
            try:
                dz = np.linalg.solve(A + lam * D, b)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            zn = np.clip(z + alpha * dz, lo, hi)
            dz = zn - z
            xn = [np.clip(x + alpha * (Np @ (r - G @ (dz / alpha)))[: x.size], *bd)
                  for x, Np, G, (r, _, _), bd in zip(xs, pinv, Gs, ev, bounds)]
            evn = pmap(lambda cx, zn=zn: _evaluate(cx[0], cx[1], op, br, unpack(zn)), list(zip(caps, xn)))
            cn = sum(float(e[2] @ e[2]) for e in evn)
            if cn < cost:
                z, xs, ev, cost = zn, xn, evn, cn
                lam = max(lam / 10.0, 1e-9)
                improved = True
                break
            lam *= 10.0
        if not improved:
            break
    return z, xs, [e[2] for e in ev], jac


def refit(windows, h, *, iters: int = 3, design_restart: bool = False):
    """``h`` (a HypothesisFit) refitted jointly by Gauss–Newton, the captures linearised again at
    the states found; ``h`` itself when the refit does not lower its χ². ``design_restart``:
    when the refit is still above the noise, also from the breaker's design state (a strong
    effect can have pushed the reduced states far from the truth: a contact wipe read as
    BC −40 %), with twice the steps; the lower χ² wins."""
    from .data import design_state

    if not h.effects:
        return h
    op, br = windows.operation, windows.breaker
    z0 = np.concatenate([np.concatenate([[h.phi[e][0]], h.phi[e][1]]) for e in h.effects])
    z, xs, rs, _ = gauss_newton(windows, h.effects, z0, h.captures, iters=iters)
    nb = sum(r.size for r in rs)
    cost = sum(float(r @ r) for r in rs)
    if design_restart and cost > nb + 5.0 * np.sqrt(2.0 * nb):
        import dataclasses

        xd = design_state(br, op)
        starts = []
        for cw in h.captures:
            x = np.asarray(cw.x, float).copy()
            x[:-1] = xd
            starts.append(dataclasses.replace(cw, x=x))
        z1, xs1, rs1, _ = gauss_newton(windows, h.effects, z, starts, iters=2 * iters)
        if sum(float(r @ r) for r in rs1) < cost:
            z, xs = z1, xs1
    _, _, _, sl = _layout(h.effects)
    eff = _unpack(z, h.effects, sl)
    return refit_if_better(h, h.effects, eff, xs, h.captures, br, op)


def holdout_shrink(windows, h):
    """Leave one capture out in linear algebra: the shared parameters' Gauss–Newton step fitted
    on the other captures (about ``h``'s fit, their states profiled), the left-out capture's
    signature predicted with it and its own state profiled. Per capture: 1 − gap_after/gap_before
    on the left-out capture (gap² = χ² − rows)."""

    if len(h.captures) < 2 or not h.effects:
        return None
    op, br = windows.operation, windows.breaker
    lo, hi, scale, sl = _layout(h.effects)
    z = np.concatenate([np.concatenate([[h.phi[e][0]], h.phi[e][1]]) for e in h.effects])
    unpack = lambda v: _unpack(v, h.effects, sl)

    def part(item):
        cw, s = item
        m0 = cw.data.y - (cw.r - s) / cw.data.weight       # the model with the effect
        G = _effect_jac(cw, cw.x, op, br, z, unpack, scale, m0, lo, hi)
        return cw.project_out(G), cw.project_out(cw.r - s), cw

    parts = pmap(part, list(zip(h.captures, h.signatures)))
    # a parameter the fit left on one of its bounds stays there (the active set): the others'
    # step is solved for the free ones only
    span = np.maximum(hi - lo, 1e-300)
    free = ((z - lo) > 1e-6 * span) & ((hi - z) > 1e-6 * span)
    parts = [(PG[:, free], e, cw) for PG, e, cw in parts]
    A = sum(PG.T @ PG for PG, _, _ in parts)
    b = sum(PG.T @ e for PG, e, _ in parts)
    out = []
    for PG, e, cw in parts:
        Aj, bj = A - PG.T @ PG, b - PG.T @ e
        k = int(free.sum())
        dz = (np.linalg.lstsq(Aj + 1e-9 * max(np.trace(Aj), 1e-300) / max(k, 1) * np.eye(k), bj, rcond=None)[0]
              if k else np.zeros(0))
        zj = np.clip(z[free] + dz, lo[free], hi[free]) - z[free]
        after_res = e - PG @ zj
        before = float(np.sum(cw.project_out(cw.r) ** 2))
        out.append(_shrink(before, float(after_res @ after_res), cw.r.size))
    return out


GN_ITERS = 3          # Gauss–Newton steps of the evidence's joint refits (``exact_fit``)
REPORT_P = 0.05   # a hypothesis below this predictive weight is neither reported nor a rival worth refitting


def fit_reported(windows, scores, rivals: int = 1, names=None):
    """The nonlinear joint refit of what is reported: ``none``, the ``rivals`` most probable
    hypotheses holding catalogued effects (by the predictive weights) and ``outside`` on the
    best of them. The evidence is not taken from these fits (``predictive`` gives it); they say
    how far the gap shrinks and what the effect does to the parameters.

    A hypothesis the evidence already refitted exactly (``scores.exact``: Gauss–Newton with each
    capture's state eliminated, a restart from the design state and a screen from every start)
    is reported as that fit, not refitted again (issue 54 item 1: the refit was 35-60 % of a
    diagnosis's integrations and changes no answer, which the scorer gives before it). Any other
    member is fitted once from its families' local refits, by the same Gauss–Newton."""
    hyps = {"none": none_fit(windows)}
    if names is None:
        names = [k for k, p in scores.ranked() if k not in ("none", "outside_catalogue") and p >= REPORT_P][:rivals]
    exact = getattr(scores, "exact", {}) or {}
    refined = getattr(scores, "refined", {}) or {}
    for name in names:
        effects = tuple(name.split("+"))
        h = exact.get(name)
        if h is None:
            if len(effects) == 1 and effects[0] in refined:
                h = refined[effects[0]]
            else:
                # from its families' local refits (or their first start)
                z0 = []
                for e in effects:
                    h1 = refined.get(e) or hyps.get(e) or fit_hypothesis(windows, (e,), [family_starts(e)[0]])
                    z0 += [h1.phi[e][0], *h1.phi[e][1]]
                h = fit_hypothesis(windows, effects, [np.array(z0, float)], refine_nfev=REFINE_NFEV)
            # polished at its own states: an opening in linear algebra (Gauss–Newton, each
            # capture's state eliminated); a closing by the trust region (its cam makes the state
            # non-smooth)
            h = refine_exact(windows, h) if windows.operation == "close" else refit(windows, h, iters=GN_ITERS)
        hyps[name] = h
    fits = Fits(windows, hyps)
    cat = [h for h in hyps.values() if h.effects]
    best = min(cat, key=lambda h: h.chi2) if cat else hyps["none"]
    hyps["outside_catalogue"] = outside_fit(windows, best)
    return fits


def exact_fit(windows, effects: tuple, refined: dict, restarts: bool = True):
    """The joint refit of a family or pair at its own nuisance profile, in linear algebra
    (``linearised.refit``: Gauss–Newton with each capture's state eliminated), from the local
    refits of its families; a pair starts from its members' parameters, unfitted.

    A closing keeps the trust-region refit (``exact_fit_trust_region``): the cam's profile makes
    the closing's state non-smooth, and the linear state step overshoots (measured on a contact
    wipe of 3 closings: Gauss–Newton stopped at χ² 22,000 where the trust region reaches 1,100
    on 1,005 blocks). ``restarts`` False: the Gauss–Newton refit only, without the restart from
    the design state and the screen from every start (``predictive.score`` keeps those for the
    leading single)."""

    if windows.operation == "close":
        return exact_fit_trust_region(windows, effects, refined)

    op, br = windows.operation, windows.breaker
    phi = {}
    for e in effects:
        if e in refined:
            phi[e] = refined[e].phi[e]
        else:                       # not refined: its first deterministic start (the refit moves it)
            z = np.asarray(best_point_w(windows, e), float)
            phi[e] = (float(z[0]), z[1:])
    if len(effects) == 1 and effects[0] in refined:
        h0 = refined[effects[0]]
    else:
        caps = windows.captures
        eff = [(e, float(phi[e][0]), np.asarray(phi[e][1], float)) for e in effects]
        sigs = [signature(cw, op, br, eff) for cw in caps]
        per = [float(np.sum(cw.project_out(cw.r - s) ** 2)) for cw, s in zip(caps, sigs)]
        h0 = HypothesisFit(tuple(effects), phi, sum(1 + len(phi[e][1]) for e in effects), float(sum(per)), per,
                           sigs, captures=list(caps))
    h = refit(windows, h0, iters=GN_ITERS, design_restart=restarts and len(effects) == 1)
    n = windows.n
    if restarts and len(effects) == 1 and h.chi2 > n + 5.0 * np.sqrt(2.0 * n):
        # the shape objective is multimodal (a contact touch's fraction moves a kink): a single
        # still above the noise is screened again from every start at the states it found
        hb = fit_hypothesis(windows, effects, family_starts(effects[0]), caps=h.captures)
        if hb.chi2 < h.chi2:
            h2 = refit(windows, hb, iters=GN_ITERS)
            if h2.chi2 < h.chi2:
                h = h2
    return h


def exact_fit_trust_region(windows, effects: tuple, refined: dict):
    """The closing's exact joint refit (``hypotheses.refine_exact``) of a family or pair, from the local
    refits of its families."""

    if len(effects) == 1:
        h = refined.get(effects[0]) or fit_hypothesis(windows, effects, [best_point_w(windows, effects[0])])
    else:
        z0 = []
        for e in effects:
            h1 = refined.get(e) or fit_hypothesis(windows, (e,), [best_point_w(windows, e)])
            z0 += [h1.phi[e][0], *h1.phi[e][1]]
        h = fit_hypothesis(windows, effects, [np.array(z0, float)], refine_nfev=REFINE_NFEV)
    h = refine_exact(windows, h)
    n = windows.n
    if len(effects) == 1 and h.chi2 > n + 5.0 * np.sqrt(2.0 * n):
        # the shape objective is multimodal (a contact touch's fraction moves a kink): a single
        # still above the noise is screened again from every start at the states it found

        hb = fit_hypothesis(windows, effects, family_starts(effects[0]), caps=h.captures)
        if hb.chi2 < h.chi2:
            h2 = refine_exact(windows, hb)
            if h2.chi2 < h.chi2:
                h = h2
    return h



def best_point_w(windows, effect):
    return family_starts(effect)[0]


def member_from_pair(windows, e: str, ph):
    """Effect ``e`` refitted alone from the pair fit ``ph``'s states and parameters (a pair must
    not win on convergence alone): Gauss–Newton on an opening, the trust region on a closing."""
    if windows.operation == "close":
        z = np.concatenate([[ph.phi[e][0]], ph.phi[e][1]])
        return refine_exact(windows, fit_hypothesis(windows, (e,), [z], caps=ph.captures, refine_nfev=REFINE_NFEV))
    eff = [(e, float(ph.phi[e][0]), np.asarray(ph.phi[e][1], float))]
    sg = [signature(cw, windows.operation, windows.breaker, eff) for cw in ph.captures]
    per = [float(np.sum(cw.project_out(cw.r - x) ** 2)) for cw, x in zip(ph.captures, sg)]
    h0 = HypothesisFit((e,), {e: ph.phi[e]}, 1 + len(ph.phi[e][1]), float(sum(per)), per, sg,
                       captures=list(ph.captures))
    return refit(windows, h0, iters=GN_ITERS)
