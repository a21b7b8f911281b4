"""``diagnose``: where the reduced model misses (phases), which catalogued effect explains it
(augmented fits, likelihood ratio, ΔBIC, hold-out), and how far it shrinks.

The verdict names an effect only when (1) the gap is significant (χ² excess over the noise
floor and a non-white residual), (2) the effect is distinguishable from a parameter change at
this noise level, (3) ΔBIC < −10 with shrink ≥ 50 %, and (4) it holds out: on other captures
when there are several, else on the held-out alternate 4 ms chunks of the window.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.stats import chi2

from ..mechanics.breaker import Breaker
from ..mechanics.coordinates import operation_coordinate
from ..mechanics.prototype import EFFECT_NAMES, OPERATIONS
from .augmented import fit_augmented, fit_reduced, state_dict
from .data import STATE, block_residual, gap_rms, model_curve, window_data
from .identifiability import absorption, jacobian
from .phases import phase_bounds
from .residuals import excess_p, phase_stats, whiteness

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
        bases.append(fit_reduced(x0, data, breaker, operation))
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
    base_curve, J = jacobian(bases[0].x, datas[0], breaker, operation)
    ident = {n: absorption(n, bases[0].x, datas[0], breaker, operation, base_curve, J) for n in catalogue}

    # Which: augmented fits, screened with a few evaluations, then the leading candidates
    # (distinguishable ones first) refitted to convergence from their screened solution.
    candidates = []
    for name in catalogue:
        candidates.append(_candidate(name, datas, bases_in, masks, breaker, operation, single, ident[name]))
    candidates.sort(key=lambda c: (not c["distinguishable"], c["delta_bic"]))
    for i, c in enumerate(candidates[:REFINE_TOP]):
        if c["delta_bic"] < 0:
            candidates[i] = _candidate(c["effect"], datas, bases_in, masks, breaker, operation, single,
                                       ident[c["effect"]], starts=c["_fits"], max_nfev=REFINE_NFEV)
    candidates.sort(key=lambda c: c["delta_bic"])

    verdict, chosen, ambiguous = decide(candidates, significant)

    how_far = None
    if chosen is not None:
        aug = chosen.pop("_fits")
        after = [_gap_report(_resid(f, d, breaker, operation), d, f, breaker, operation, bounds_from=b)
                 for f, d, b in zip(aug, datas, bases)]
        how_far = {"effect": chosen["effect"], "strength": chosen["strength"],
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
        "gap": gap, "significant_gap": bool(significant), "candidates": candidates,
        "verdict": verdict, "ambiguous": ambiguous, "how_far": how_far, "absorbed": absorbed,
        "identifiability": list(ident.values()), "warnings": warnings,
        "holdout": "alternate 4 ms chunks of the window" if single else "leave one capture out",
        "runtime_s": time.perf_counter() - t_run,
    }


def qualifies(c) -> bool:
    """A candidate that could be the verdict on its own: distinguishable, ΔBIC < −10, shrink ≥
    50 % and hold-out shrink ≥ 40 %."""
    return bool(c["distinguishable"] and c["delta_bic"] < MAX_DELTA_BIC and c["shrink"] >= MIN_SHRINK
                and c["holdout_shrink"] >= MIN_HOLDOUT)


def decide(candidates, significant: bool, exclude=()):
    """The verdict from the candidates (any order): ``(verdict, chosen candidate or None,
    ambiguous effect names)``.

    ``none`` without a significant gap. Otherwise the best qualifying candidate (lowest ΔBIC),
    provided it beats every other distinguishable candidate with ΔBIC < −10 by a margin of
    max(MARGIN_BIC, MARGIN_REL·|ΔBIC|); if a rival comes that close the verdict is
    ``unexplained`` and both are listed as ``ambiguous`` (never a confident guess between two
    effects that explain the gap equally well). ``exclude`` drops effects from the catalogue
    (the leave-one-effect-out check).
    """
    if not significant:
        return "none", None, []
    pool = sorted((c for c in candidates if c["effect"] not in exclude), key=lambda c: c["delta_bic"])
    best = next((c for c in pool if qualifies(c)), None)
    if best is None:
        return "unexplained", None, []
    margin = max(MARGIN_BIC, MARGIN_REL * abs(best["delta_bic"]))
    rivals = [c["effect"] for c in pool if c is not best and c["distinguishable"]
              and c["delta_bic"] < MAX_DELTA_BIC and c["delta_bic"] < best["delta_bic"] + margin]
    if rivals:
        return "unexplained", None, [best["effect"]] + rivals
    return best["effect"], best, []


def _check_breaker(cap, breaker, operation):
    """A capture whose stroke is not the breaker's comes from another breaker (or channel)."""
    y = operation_coordinate(np.asarray(cap.travel, float), operation, breaker.stroke)
    n = max(int(0.002 * cap.sample_rate), 4)
    head, peak = float(np.median(y[:n])), float(np.max(np.convolve(y, np.ones(n) / n, "valid")))
    span = peak - head
    if span > 0.1 * breaker.stroke and not 0.75 * breaker.stroke <= span <= 1.35 * breaker.stroke:
        raise DiagnosisError(
            f"{cap.source or 'capture'}: the travel moves {span:.3f} rad but breaker '{breaker.name}' "
            f"has a {breaker.stroke:.3f} rad stroke: wrong breaker file for this capture?")


def _chunk_mask(d):
    """In-sample blocks: even 4 ms chunks; the odd chunks are held out."""
    return (np.floor(d.t / CHUNK_S).astype(int) % 2) == 0


def _resid(fit, d, breaker, operation):
    m, _ = model_curve(fit.x, d, breaker, operation, fit.effect, fit.strength)
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
               max_nfev=None):
    kw = {} if max_nfev is None else {"max_nfev": max_nfev}
    starts = starts or [None] * len(datas)
    aug = [fit_augmented(b, d, breaker, operation, name, m, start=s0, **kw)
           for b, d, m, s0 in zip(bases, datas, masks, starts)]
    r0 = [_resid(b, d, breaker, operation) for b, d in zip(bases, datas)]
    r1 = [_resid(f, d, breaker, operation) for f, d in zip(aug, datas)]
    w = [np.sqrt(d.count) / d.noise for d in datas]
    rss0 = float(sum(np.sum((a * b) ** 2) for a, b in zip(r0, w)))
    rss1 = float(sum(np.sum((a * b) ** 2) for a, b in zip(r1, w)))
    n = sum(d.t.size for d in datas)
    k = len(datas)  # one strength per capture
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
            s = float(np.median([f.strength for j, f in enumerate(aug) if j != i]))
            f = fit_augmented(b, d, breaker, operation, name, strength=s)
            hs.append(_shrink(r0[i], _resid(f, d, breaker, operation), d.count, d.noise))
        holdout = float(np.mean(hs))
    base_p = state_dict(bases[0], operation)
    new_p = state_dict(aug[0], operation)
    return {"effect": name, "strength": float(np.median([f.strength for f in aug])),
            "rmse_rad": float(np.sqrt(g1 * g1 + noise**2)), "shrink": shrink,
            "delta_bic": float(-lr + k * np.log(n)), "lr_p_value": float(chi2.sf(max(lr, 0.0), k)),
            "holdout_shrink": holdout, "distinguishable": ident["distinguishable"],
            "parameter_shift": {kk: float(100 * (new_p[kk] / base_p[kk] - 1)) for kk in base_p},
            "_fits": aug}


def _plausibility(bases, breaker, operation):
    design = breaker.design_parameters()
    out = []
    for k, v in state_dict(bases[0], operation).items():
        dv = design[k]
        if abs(v / dv - 1) > PLAUSIBLE:
            out.append(f"fitted {k} = {v:.4g} is {100 * (v / dv - 1):+.0f} % from the design value "
                       f"{dv:.4g} implied by the breaker file")
    return out
