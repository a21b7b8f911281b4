"""``diagnose``: where the reduced model misses (phases), which catalogued effect explains it
(augmented fits, likelihood ratio, ΔBIC, hold-out), and how far it shrinks.

The verdict names an effect only when (1) the gap is significant: χ² excess over the noise
floor with a non-white residual, or a targeted likelihood-ratio test (some effect's ΔBIC <
−10); (2) the effect is distinguishable from a parameter change at this noise level; (3) ΔBIC
< −10 with shrink ≥ 50 %, also in the worst phase; (4) it acts where the gap is (the worst
phase is in its catalogue region or carries a fair share of its unabsorbed signature) and
explains the gap phase by phase; (5) it holds out: on other captures when there are several,
else on the held-out alternate 4 ms chunks of the window; (6) no other credible effect comes
within the ΔBIC margin.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.stats import chi2

from ..mechanics.breaker import Breaker
from ..mechanics.coordinates import operation_coordinate
from ..prototypes.a import EFFECT_NAMES, FAMILY, LOCALITY, OPERATIONS, REGIONS, SHAPES
from .augmented import fit_augmented, fit_reduced, n_shapes, state_dict
from .data import STATE, block_residual, gap_rms, model_curve, window_data
from .identifiability import absorption, jacobian
from .phases import phase_bounds
from .residuals import phase_stats, whiteness

CHUNK_S = 4e-3          # hold-out chunk length [s]
MIN_SHRINK = 0.5
MIN_HOLDOUT = 0.4
MAX_DELTA_BIC = -10.0
GAP_P = 1e-3            # significance of the gap (χ² excess)
WHITE_P = 0.01          # Ljung–Box
MIN_GAP_NOISE = 0.25    # gap RMS must reach this fraction of the noise floor
PLAUSIBLE = 0.25        # warn when a fitted parameter is this far from the design value
REFINE_TOP = 3          # screened candidates refitted to convergence
REFINE_NFEV = 40
MARGIN_BIC = 10.0       # the verdict must beat the runner-up's ΔBIC by this much ...
MARGIN_REL = 0.02       # ... and by this fraction of its own |ΔBIC|
BASE_NFEV = 30          # polish of the reduced baseline
COLD_BELOW = 0.8        # refinement also tries a cold start when the screened shrink is below
AFTER_P = 1e-3          # residual after the named effect's fit: phase-wise χ² (Bonferroni)
MIN_WORST_SHRINK = 0.5  # the gap in the worst phase must shrink this much
MIN_REGION_SHARE = 0.2  # ... or this share of its unabsorbed signature in the worst phase
LOCAL_GAP_SHARE = 0.6   # a local effect "acts where the gap is": this share of the gap in its region


class DiagnosisError(ValueError):
    """The captures cannot be diagnosed: the message says why."""


def diagnose(captures, breaker: Breaker, operation: str, *, effects=None, seed: int = 1,
             fitter=None) -> dict:
    """Diagnose the sim-to-real gap of one or more captures of the same operation.

    Parameters
    ----------
    captures : sequence of Capture
    breaker : Breaker
    operation : {"open", "close"}
    effects : sequence of str, optional
        The catalogue to try (default: every effect acting on ``operation``).
    seed : int
        Seed of the reduced-model fit.
    fitter : callable, optional
        ``fitter(capture, breaker, operation, seed=...) -> FitResult``; default
        ``service.estimation.fit_capture``.

    Returns
    -------
    dict
        JSON-able: ``gap``, ``candidates``, ``verdict``, ``absorbed``, ``warnings``, ... (see
        docs/diagnosis.md).
    """
    t_run = time.perf_counter()
    if operation not in ("open", "close"):
        raise DiagnosisError(f"operation must be 'open' or 'close', got {operation!r}")
    if not captures:
        raise DiagnosisError("no capture given")
    catalogue = [n for n in (effects or EFFECT_NAMES) if operation in OPERATIONS.get(n, ())]
    unknown = [n for n in (effects or []) if n not in EFFECT_NAMES]
    if unknown:
        raise DiagnosisError(f"unknown effect(s) {', '.join(unknown)}")
    if fitter is None:
        from ..estimation import fit_capture as fitter
    datas, bases, fits = [], [], []
    for cap in captures:
        _check_breaker(cap, breaker, operation)
        try:
            fr = fitter(cap, breaker, operation, seed=seed)
        except ValueError as exc:
            raise DiagnosisError(str(exc)) from None
        data = window_data(cap, fr, breaker, operation)
        x0 = np.array([fr.parameters[k] for k in STATE[operation]] + [fr.onset_delay_s])
        fits.append(fr)
        datas.append(data)
        bases.append(_baseline(x0, data, breaker, operation))
    single = len(captures) == 1
    masks = [_chunk_mask(d) if single else np.ones(d.t.size, bool) for d in datas]
    bases_in = [fit_reduced(b.x, d, breaker, operation, m) if single else b
                for b, d, m in zip(bases, datas, masks)]

    # Where: the baseline gap by phase, on the full-window reduced fit.
    per_capture, res0 = [], []
    for d, b in zip(datas, bases):
        r = _resid(b, d, breaker, operation)
        res0.append(r)
        per_capture.append(_gap_report(r, d, b, breaker, operation))
    gap = _pooled_gap(res0, datas)
    gap["phases"] = per_capture[0]["phases"]
    significant = (gap["p_value"] < GAP_P and gap["ljung_box_p"] < WHITE_P
                   and gap["gap_rad"] >= MIN_GAP_NOISE * gap["noise_rad"])

    # Absorbed or distinguishable, at this capture's noise and fitted state.
    bounds = [_bounds_of(b, d, breaker, operation) for b, d in zip(bases, datas)]
    base_curve, J = jacobian(bases[0].x, datas[0], breaker, operation)
    ident = {n: absorption(n, bases[0].x, datas[0], breaker, operation, base_curve, J, bounds[0])
             for n in catalogue}
    worst = max(gap["phases"], key=lambda p: p["ratio_to_noise"])["name"]
    ctx = {"bounds": bounds, "worst": worst, "phases0": [pc["phases"] for pc in per_capture],
           "operation": operation}

    # Which: augmented fits, screened with a few evaluations, then the leading candidates
    # (distinguishable ones first) refitted to convergence from their screened solution.
    candidates = []
    for name in catalogue:
        candidates.append(_candidate(name, datas, bases_in, masks, breaker, operation, single, ident[name],
                                     ctx=ctx))
    candidates.sort(key=lambda c: (not c["distinguishable"], c["delta_bic"]))
    for i, c in enumerate(candidates[:REFINE_TOP]):
        if c["delta_bic"] < 0:
            candidates[i] = _candidate(c["effect"], datas, bases_in, masks, breaker, operation, single,
                                       ident[c["effect"]], starts=c["_fits"], max_nfev=REFINE_NFEV, ctx=ctx,
                                       cold=c["shrink"] < COLD_BELOW)
    candidates.sort(key=lambda c: c["delta_bic"])

    verdict, chosen, ambiguous, family = decide(candidates, significant, detail=True)
    significant_lr = lr_significant(candidates)

    how_far = None
    if chosen is not None:
        aug = chosen.pop("_fits")
        after = [_gap_report(_resid(f, d, breaker, operation), d, f, breaker, operation, bounds_from=b)
                 for f, d, b in zip(aug, datas, bases)]
        rest = max(after[0]["phases"], key=lambda p: p["ratio_to_noise"])
        how_far = {"effect": chosen["effect"], "strength": chosen["strength"], "shape": chosen["shape"],
                   "explained_fraction": chosen["explained_fraction"],
                   "rest_phase": rest["name"] if chosen["after_p"] < AFTER_P else None,
                   "rmse_rad_before": gap["rmse_rad"],
                   "rmse_rad_after": _pooled_gap([_resid(f, d, breaker, operation) for f, d in zip(aug, datas)],
                                                 datas)["rmse_rad"],
                   "shrink": chosen["shrink"], "phases_after": after[0]["phases"],
                   "corrected_parameters": state_dict(aug[0], operation), "onset_delay_s": float(aug[0].x[-1]),
                   "parameter_shift": chosen["parameter_shift"]}
    for c in candidates:
        c.pop("_fits", None)

    warnings = _plausibility(bases, breaker, operation)
    absorbed = [{"effect": n, "parameter_shift": v["parameter_shift"], "residual_rad": v["residual_rad"],
                 "strength": v["strength"]} for n, v in ident.items() if not v["distinguishable"]]
    if verdict == "none" and warnings and absorbed:
        warnings.append("the residual is at the noise floor but parameters are far from the design: "
                        "an absorbed effect (" + ", ".join(a["effect"] for a in absorbed) +
                        ") or a real change of state may explain it")
    return {
        "operation": operation, "breaker": breaker.name, "captures": [
            {"source": d.source, "reduced_parameters": state_dict(b, operation),
             "onset_delay_s": float(b.x[-1]), **pc} for d, b, pc in zip(datas, bases, per_capture)],
        "gap": gap, "significant_gap": bool(significant or significant_lr),
        "significant_chi2": bool(significant), "significant_lr": bool(significant_lr),
        "worst_phase": worst, "candidates": candidates,
        "verdict": verdict, "ambiguous": ambiguous, "ambiguous_family": family,
        "status": _status(verdict, chosen, ambiguous),
        "explained_fraction": chosen["explained_fraction"] if chosen is not None else (
            None if verdict == "none" else 0.0),
        "how_far": how_far, "absorbed": absorbed,
        "identifiability": list(ident.values()), "warnings": warnings,
        "holdout": "alternate 4 ms chunks of the window" if single else "leave one capture out",
        "runtime_s": time.perf_counter() - t_run,
    }


def qualifies(c) -> bool:
    """A candidate that could be the verdict on its own: ΔBIC < −10 (shape parameters paid for),
    shrink ≥ 50 % in-sample and ≥ 40 % on the hold-out, the gap in the worst phase shrinks by
    ≥ 50 %, and it acts where the gap is (:func:`credible`). The a-priori identifiability check
    does not veto it: an effect the data explain is named even if its realistic-strength form
    would be absorbed."""
    return bool(c["delta_bic"] < MAX_DELTA_BIC and c["shrink"] >= MIN_SHRINK
                and c["holdout_shrink"] >= MIN_HOLDOUT and credible(c)
                and c.get("worst_phase_shrink", 1.0) >= MIN_WORST_SHRINK)


def credible(c) -> bool:
    """The effect acts where the gap is: the worst phase is in its catalogue region or holds
    ≥ MIN_REGION_SHARE of its unabsorbed signature."""
    return bool(c.get("in_region", True))


def lr_significant(candidates, exclude=()) -> bool:
    """The gap is significant by a targeted test: some catalogued effect's likelihood-ratio test
    against the reduced model gives ΔBIC < MAX_DELTA_BIC (LR > 10 + k·ln n). More powerful than
    the omnibus χ² when the gap has a shape."""
    return any(c["delta_bic"] < MAX_DELTA_BIC for c in candidates if c["effect"] not in exclude)


def _prefers_local(c) -> bool:
    """A phase-local effect that acts where the gap is: most of the baseline gap lies in its region."""
    return bool(c.get("locality") == "local" and qualifies(c)
                and c.get("region_gap_share", 0.0) >= LOCAL_GAP_SHARE)


def decide(candidates, significant: bool, exclude=(), detail: bool = False):
    """The verdict from the candidates (any order): ``(verdict, chosen candidate or None,
    ambiguous effect names)`` (with ``detail``, a 4th item: the shared family name or None).

    ``none`` without a significant gap (omnibus test, or :func:`lr_significant` on the catalogue
    left after ``exclude``). Otherwise the best qualifying candidate (lowest ΔBIC), provided it
    beats every other credible candidate with ΔBIC < −10 and shrink ≥ MIN_SHRINK by a margin of
    max(MARGIN_BIC, MARGIN_REL·|ΔBIC|). Among rivals that close, a single phase-local effect
    acting where the gap is (most of the gap in its region) wins over whole-stroke effects,
    which fit almost any smooth gap. Otherwise the verdict is ``unexplained`` and the rivals are
    listed, ranked, as ``ambiguous`` (with their family's name when they share one).
    ``exclude`` drops effects from the catalogue (the leave-one-effect-out check).
    """
    pool = sorted((c for c in candidates if c["effect"] not in exclude), key=lambda c: c["delta_bic"])

    def out(v, ch, amb, fam=None):
        return (v, ch, amb, fam) if detail else (v, ch, amb)

    if not (significant or lr_significant(pool)):
        return out("none", None, [])
    best = next((c for c in pool if qualifies(c)), None)
    if best is None:
        return out("unexplained", None, [])
    margin = max(MARGIN_BIC, MARGIN_REL * abs(best["delta_bic"]))
    rivals = [c for c in pool if c is not best and credible(c) and c["shrink"] >= MIN_SHRINK
              and c["delta_bic"] < MAX_DELTA_BIC and c["delta_bic"] < best["delta_bic"] + margin]
    if not rivals:
        return out(best["effect"], best, [])
    group = [best] + rivals
    local = [c for c in group if _prefers_local(c)]
    if len(local) == 1 and all(c.get("locality") != "local" for c in group if c is not local[0]):
        return out(local[0]["effect"], local[0], [])
    names = [c["effect"] for c in group]
    fams = {FAMILY[n] for n in names}
    return out("unexplained", None, names, fams.pop() if len(fams) == 1 else None)


def _status(verdict, chosen, ambiguous) -> str:
    """``explained`` (the residual after the named effect is at the noise floor),
    ``partly_explained``, ``ambiguous`` (rivals within the margin), ``unexplained`` or ``none``."""
    if verdict == "none":
        return "none"
    if chosen is None:
        return "ambiguous" if ambiguous else "unexplained"
    return "explained" if chosen.get("after_p", 1.0) >= AFTER_P else "partly_explained"


def _check_breaker(cap, breaker, operation):
    """A capture whose stroke is not the breaker's comes from another breaker (or channel)."""
    y = operation_coordinate(np.asarray(cap.travel, float), operation, breaker.stroke)
    n = min(max(int(0.002 * cap.sample_rate), 4), y.size)
    # the largest average over n samples, over full windows only
    head, peak = float(np.median(y[:n])), float(np.max(uniform_filter1d(y, n)[n // 2: y.size - n + n // 2 + 1]))
    span = peak - head
    if span > 0.1 * breaker.stroke and not 0.75 * breaker.stroke <= span <= 1.35 * breaker.stroke:
        raise DiagnosisError(
            f"{cap.source or 'capture'}: the travel moves {span:.3f} rad but breaker '{breaker.name}' "
            f"has a {breaker.stroke:.3f} rad stroke: wrong breaker file for this capture?")


def _chunk_mask(d):
    """In-sample blocks: even 4 ms chunks; the odd chunks are held out."""
    return (np.floor(d.t / CHUNK_S).astype(int) % 2) == 0


def _resid(fit, d, breaker, operation):
    m, _ = model_curve(fit.x, d, breaker, operation, fit.effect, fit.strength, shape=fit.shape)
    return d.y - m


def _gap_report(r, d, fit, breaker, operation, bounds_from=None):
    ref = bounds_from or fit
    tm = d.t - ref.x[-1]
    theta, _ = model_curve(ref.x, d, breaker, operation, None)
    bounds = phase_bounds(operation, tm, theta, float(tm[-1]), breaker)
    g = gap_rms(r, d.count, d.noise)
    return {"rmse_rad": float(np.sqrt(g * g + d.noise**2)), "gap_rad": g, "noise_rad": d.noise,
            "phases": phase_stats(r, d, bounds, ref.x[-1])}


def _pooled_gap(rs, datas):
    r = np.concatenate(rs)
    count = np.concatenate([d.count for d in datas])
    noise = float(np.sqrt(np.mean([d.noise**2 for d in datas])))
    g = gap_rms(r, count, noise)
    stat = float(np.sum(r * r * count)) / noise**2
    lb = min(whiteness(ri, d) for ri, d in zip(rs, datas))
    return {"rmse_rad": float(np.sqrt(g * g + noise**2)), "noise_rad": noise, "gap_rad": g,
            "ratio_to_noise": float(np.sqrt(g * g + noise**2)) / noise,
            "p_value": float(chi2.sf(stat, r.size)), "ljung_box_p": lb}


def _shrink(r0, r1, count, noise):
    g0, g1 = gap_rms(r0, count, noise), gap_rms(r1, count, noise)
    return 0.0 if g0 <= 0 else float(1.0 - g1 / g0)


def _candidate(name, datas, bases, masks, breaker, operation, single, ident, starts=None,
               max_nfev=None, ctx=None, cold=True):
    kw = {} if max_nfev is None else {"max_nfev": max_nfev}
    if starts is not None:
        kw["cold"] = cold
    starts = starts or [None] * len(datas)
    aug = [fit_augmented(b, d, breaker, operation, name, m, start=s0, **kw)
           for b, d, m, s0 in zip(bases, datas, masks, starts)]
    r0 = [_resid(b, d, breaker, operation) for b, d in zip(bases, datas)]
    r1 = [_resid(f, d, breaker, operation) for f, d in zip(aug, datas)]
    w = [np.sqrt(d.count) / d.noise for d in datas]
    rss0 = float(sum(np.sum((a * b) ** 2) for a, b in zip(r0, w)))
    rss1 = float(sum(np.sum((a * b) ** 2) for a, b in zip(r1, w)))
    n = sum(d.t.size for d in datas)
    k = len(datas) * (1 + n_shapes(name))  # strength and shape parameters per capture
    lr = float(n * np.log(rss0 / max(rss1, 1e-300)))
    count = np.concatenate([d.count for d in datas])
    noise = float(np.sqrt(np.mean([d.noise**2 for d in datas])))
    shrink = _shrink(np.concatenate(r0), np.concatenate(r1), count, noise)
    g1 = gap_rms(np.concatenate(r1), count, noise)
    if single:
        held = ~masks[0]
        holdout = _shrink(r0[0][held], r1[0][held], datas[0].count[held], datas[0].noise)
    else:
        hs = []
        for i, (b, d) in enumerate(zip(bases, datas)):
            others = [f for j, f in enumerate(aug) if j != i]
            s = float(np.median([f.strength for f in others]))
            sh = np.median([f.shape for f in others], axis=0) if others[0].shape is not None else None
            f = fit_augmented(b, d, breaker, operation, name, strength=s, shape=sh)
            hs.append(_shrink(r0[i], _resid(f, d, breaker, operation), d.count, d.noise))
        holdout = float(np.mean(hs))
    base_p = state_dict(bases[0], operation)
    new_p = state_dict(aug[0], operation)
    return {"effect": name, "strength": float(np.median([f.strength for f in aug])),
            "shape": _shape_dict(name, aug[0]), "locality": LOCALITY[name],
            "rmse_rad": float(np.sqrt(g1 * g1 + noise**2)), "shrink": shrink,
            "delta_bic": float(-lr + k * np.log(n)), "lr_p_value": float(chi2.sf(max(lr, 0.0), k)),
            "holdout_shrink": holdout, "distinguishable": ident["distinguishable"],
            "explained_fraction": float(1.0 - (1.0 - shrink) ** 2) if shrink > 0 else 0.0,
            "parameter_shift": {kk: float(100 * (new_p[kk] / base_p[kk] - 1)) for kk in base_p},
            **_after_checks(r1, datas, bases, ctx, ident), "_fits": aug}


def _shape_dict(name, fit):
    if fit.shape is None:
        return {}
    return {sh[0]: float(v) for sh, v in zip(SHAPES[name], fit.shape)}


def _after_checks(r1, datas, bases, ctx, ident):
    """Where the candidate leaves the residual, on the first capture's phases:

    - ``after_p``: χ² p of the residual after its fit, Bonferroni over the phases (and captures);
    - ``worst_phase_shrink``: the shrink of the gap in the baseline's worst phase;
    - ``phase_shrink_min``: the smallest shrink over the phases where the baseline gap was
      significant (p < GAP_P) — the effect must explain the gap wherever it is;
    - ``worst_phase_share``: the share of the effect's unabsorbed signature (identifiability
      check) lying in the worst phase;
    - ``in_region``: the worst phase is in the catalogue's region of the effect (REGIONS), or
      carries ≥ MIN_REGION_SHARE of its unabsorbed signature.
    """
    if ctx is None:
        return {}
    ps, out = [], {}
    for i, (r, d, b, bnd) in enumerate(zip(r1, datas, bases, ctx["bounds"])):
        st = phase_stats(r, d, bnd, b.x[-1])
        ps += [p["p_value"] for p in st if p["samples"] > 0]
        if i == 0:
            shr = {}
            for p0, p1 in zip(ctx["phases0"][0], st):
                g0, g1 = p0["gap_rad"], p1["gap_rad"]
                shr[p0["name"]] = (0.0 if g0 <= 0 else float(1.0 - g1 / g0), p0["p_value"] < GAP_P, p1)
            out["worst_phase_shrink"] = shr[ctx["worst"]][0]
            sig = [v[0] for v in shr.values() if v[1]]
            out["phase_shrink_min"] = float(min(sig)) if sig else 1.0
    out["after_p"] = float(min(1.0, len(ps) * min(ps))) if ps else 1.0
    share = float(ident.get("phase_share", {}).get(ctx["worst"], 1.0))
    out["worst_phase_share"] = share
    region = REGIONS[ctx["operation"]].get(ident["effect"], ())
    energy = {p["name"]: p["gap_rad"] ** 2 * p["samples"] for p in ctx["phases0"][0]}
    out["region_gap_share"] = float(sum(v for k, v in energy.items() if k in region)
                                    / max(sum(energy.values()), 1e-300))
    out["in_region"] = bool(ctx["worst"] in REGIONS[ctx["operation"]].get(ident["effect"], ())
                            or share >= MIN_REGION_SHARE)
    return out


def _baseline(x0, data, breaker, operation):
    """The reduced fit polished from the estimator's solution and, when that leaves a
    significant excess, also from the breaker's design state (τ from a coarse scan): the lower
    cost wins. An unconverged or locally-trapped baseline otherwise shows up as a spurious gap
    that any effect with a free strength 'explains' (a cam-friction capture named viscous)."""
    best = fit_reduced(x0, data, breaker, operation, max_nfev=BASE_NFEV)
    cost = float(np.sum(block_residual(best.x, data, breaker, operation) ** 2))
    if chi2.sf(cost, data.t.size) >= GAP_P:
        return best
    design = breaker.design_parameters()
    xd = np.array([design[k] for k in STATE[operation]] + [0.0])
    taus = np.linspace(-1.5e-3, 4.5e-3, 25)
    costs = []
    for tau in taus:
        xd[-1] = tau
        costs.append(float(np.sum(block_residual(xd, data, breaker, operation) ** 2)))
    xd[-1] = taus[int(np.argmin(costs))]
    alt = fit_reduced(xd, data, breaker, operation, max_nfev=BASE_NFEV)
    alt_cost = float(np.sum(block_residual(alt.x, data, breaker, operation) ** 2))
    if alt_cost < cost:
        return alt
    return best


def _bounds_of(fit, d, breaker, operation):
    tm = d.t - fit.x[-1]
    theta, _ = model_curve(fit.x, d, breaker, operation, None)
    return phase_bounds(operation, tm, theta, float(tm[-1]), breaker)


def _plausibility(bases, breaker, operation):
    design = breaker.design_parameters()
    out = []
    for k, v in state_dict(bases[0], operation).items():
        dv = design[k]
        if abs(v / dv - 1) > PLAUSIBLE:
            out.append(f"fitted {k} = {v:.4g} is {100 * (v / dv - 1):+.0f} % from the design value "
                       f"{dv:.4g} implied by the breaker file")
    return out
