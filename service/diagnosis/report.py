"""Stage 5 — the report: the JSON-ready result (the contract in docs/diagnosis.md), its plain
text form and the residual plot."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..mechanics.effects import SHAPES, in_words
from .data import STATE, model_curve
from .decision import Decision
from .discrepancy import KNOT_S
from .evidence import Evidence
from .hypotheses import Fits, signature
from .phases import phase_bounds
from .whiteness import ljung_box


def _ratio(z, block: float) -> float:
    """rmse/noise per sample from whitened block-mean residuals z (noise included), blocks of
    ``block`` samples."""
    if z.size == 0:
        return 1.0
    return float(np.sqrt(1.0 + max(float(np.mean(z * z)) - 1.0, 0.0) / block))


def _params(x, operation, extra=None):
    d = {k: float(v) for k, v in zip(STATE[operation], x)}
    d["onset_delay_s"] = float(x[-1])
    return d


def _effects_hypothesis(fits: Fits, dec: Decision):
    """The hypothesis whose effects the materiality describes: the answer's, or (none, outside)
    the most probable one holding effects."""
    h = fits.hypotheses[dec.hypothesis]
    if h.effects:
        return h
    for name, _ in sorted(dec.probabilities.items(), key=lambda kv: -kv[1]):
        if name in fits.hypotheses and fits.hypotheses[name].effects:
            return fits.hypotheses[name]
    return None


def materiality(fits: Fits, ev: Evidence, dec: Decision) -> dict:
    """How big the gap is and what the fitted effect does to the parameters, beside the answer
    (never changing it). The gap per sample [σ] with a 95 % interval from the noncentral χ²
    (sd √(2n + 4λ), λ = χ² − n); per effect its fitted strength with a 95 % interval (the
    signature is linear in the strength to first order: sd = |s|·√(s²/Σ‖P⊥sig‖²)), its unabsorbed
    contribution [σ per sample], the relative bias it puts into each reduced parameter, and
    ``material``: that contribution exceeds σ/√block, the sd of one block mean."""
    w = fits.windows
    n, block = ev.n, w.block
    lam = max(fits.hypotheses["none"].chi2 / ev.s2 - n, 0.0)
    sd = float(np.sqrt(2 * n + 4 * lam))

    def g(x):
        return float(np.sqrt(max(x, 0.0) / n / block))

    out = {"gap_sigma": g(lam), "gap_sigma_interval": [g(lam - 1.96 * sd), g(lam + 1.96 * sd)], "effects": []}
    h = _effects_hypothesis(fits, dec)
    if h is None:
        return out
    names = STATE[w.operation]
    for e, st, sh in h.as_effects():
        sigs = [signature(cw, w.operation, w.breaker, [(e, st, sh)]) for cw in h.captures]
        u = sum(float(np.sum(cw.project_out(s) ** 2)) for cw, s in zip(h.captures, sigs))
        sd_s = abs(st) * float(np.sqrt(ev.s2 / u)) if u > 0 else float("inf")
        bias = np.mean([cw.state_step(s) / np.where(cw.x == 0, 1.0, cw.x) for cw, s in zip(h.captures, sigs)], axis=0)
        contrib = float(np.sqrt(u / n / block))
        out["effects"].append({
            "effect": e, "in_words": in_words(e), "strength": float(st),
            "strength_interval": [float(st - 1.96 * sd_s), float(st + 1.96 * sd_s)],
            "shape": {nm[0]: float(v) for nm, v in zip(SHAPES[e], sh)},
            "contribution_sigma": contrib, "material": contrib >= 1.0 / np.sqrt(block),
            "bias": {k: float(v) for k, v in zip(names, bias[:len(names)])}})
    return out


def discrepancy_report(fits: Fits, ev: Evidence) -> dict:
    """Where the part no catalogued hypothesis explains lies: the discrepancy term's posterior
    mean (at its most probable amplitude) per phase [mrad rms and noise floors] and its peak
    [ms after the motion onset, phase]; ``shape`` "transient" when half its energy lies within
    2 ms, else "spread"."""
    out = fits.hypotheses["outside_catalogue"]
    w = fits.windows
    fitted = out.discrepancy.posterior_fit(ev.s2)
    per_phase, peak, energy = {}, (0.0, None, None), []
    for cw, d in zip(out.captures, fitted):
        rad = d / cw.data.weight
        tau = float(cw.x[-1])
        tm = cw.data.t - tau
        theta = model_curve(cw.x, cw.data, w.breaker, w.operation)
        for name, a, b in phase_bounds(w.operation, tm, theta, float(tm[-1]), w.breaker):
            sel = (tm >= a) & (tm <= b)
            acc = per_phase.setdefault(name, [])
            acc.append(rad[sel])
            if np.any(sel):
                i = int(np.argmax(np.abs(rad) * sel))
                if abs(rad[i]) > peak[0]:
                    peak = (float(abs(rad[i])), float(tm[i]), name)
        energy.append((tm, rad * rad))
    noise = float(np.sqrt(np.mean([cw.data.noise ** 2 for cw in out.captures])))
    phases = []
    for name, parts in per_phase.items():
        v = np.concatenate(parts) if parts else np.zeros(0)
        rms = float(np.sqrt(np.mean(v * v))) if v.size else 0.0
        phases.append({"phase": name, "rms_mrad": 1e3 * rms, "rms_noise": rms / noise if noise > 0 else 0.0})
    shape = "none"
    if peak[1] is not None:
        near = sum(float(np.sum(e[np.abs(t - peak[1]) <= 1e-3])) for t, e in energy)
        total = sum(float(np.sum(e)) for _, e in energy)
        shape = "transient" if total > 0 and near >= 0.5 * total else "spread"
    return {"log_bayes_factor": ev.log_bf_discrepancy, "phases": phases,
            "peak": {"mrad": 1e3 * peak[0], "t_ms": None if peak[1] is None else 1e3 * peak[1], "phase": peak[2]},
            "shape": shape, "knot_spacing_ms": 1e3 * KNOT_S}


def predictive_report(scores, dec: Decision) -> dict | None:
    """The evidence in its own units: per unit (capture, or ~2 ms stretch of one capture) the
    LOO log predictive density of the leading hypotheses against ``none``, the elpd difference
    of the first two with its standard error, and the linear fit's gap shrink."""
    if scores is None:
        return None
    hyp = scores.features["hypotheses"]
    ranked = [k for k, _ in sorted(dec.probabilities.items(), key=lambda kv: -kv[1]) if k in hyp]
    a, b = ranked[0], ranked[1] if len(ranked) > 1 else ranked[0]
    d = np.asarray(hyp[a]["lpd"], float) - np.asarray(hyp[b]["lpd"], float)
    se = float(np.sqrt(d.size * np.var(d, ddof=1))) if d.size > 1 else float("inf")
    return {"units": scores.units, "n_units": scores.n_units,
            "elpd": {k: float(hyp[k]["elpd"]) for k in sorted(hyp, key=lambda k: -hyp[k]["elpd"])},
            "per_unit": {k: [float(x) for x in hyp[k]["lpd"]] for k in ranked[:3]},
            "first_two": [a, b], "elpd_difference": float(hyp[a]["elpd"] - hyp[b]["elpd"]),
            "elpd_difference_se": se if a != b else 0.0,
            "dimension": {k: int(v["dim"]) for k, v in hyp.items()},
            "noise_ar": [{"coefficients": c, "innovation_sd": sd} for c, sd in scores.noise_ar],
            "method": "leave-one-capture-out predictive density (the features), probabilities by the learnt "
                      "scorer (service/diagnosis/scorer.py)"}


def build(fits: Fits, ev: Evidence, dec: Decision, next_meas: list, holdout, runtime_s: float,
          scores=None) -> dict:
    w = fits.windows
    op, br, caps = w.operation, w.breaker, w.captures
    block = w.block
    chosen = fits.hypotheses[dec.hypothesis]
    if dec.status != "named":
        chosen = fits.hypotheses["none"]
    after = [cw.project_out(cw.r - s) for cw, s in zip(chosen.captures, chosen.signatures)]
    before = [cw.project_out(cw.r) for cw in caps]

    # where: phases of each capture's fitted reduced curve, pooled over captures
    where = []
    per_phase = {}
    for cw, zb, za in zip(caps, before, after):
        d = cw.data
        theta = model_curve(cw.x, d, br, op)
        tm = d.t - cw.x[-1]
        for name, a, b in phase_bounds(op, tm, theta, float(tm[-1]), br):
            sel = (tm >= a) & (tm <= b)
            acc = per_phase.setdefault(name, {"t0_s": d.t_start + cw.x[-1] + a, "t1_s": d.t_start + cw.x[-1] + b,
                                              "zb": [], "za": []})
            acc["zb"].append(zb[sel])
            acc["za"].append(za[sel])
    for name, acc in per_phase.items():
        where.append({"phase": name, "t0_s": float(acc["t0_s"]), "t1_s": float(acc["t1_s"]),
                      "gap_before": _ratio(np.concatenate(acc["zb"]), block),
                      "gap_after": _ratio(np.concatenate(acc["za"]), block)})

    noise = float(np.sqrt(np.mean([cw.data.noise ** 2 for cw in caps])))
    zb, za = np.concatenate(before), np.concatenate(after)
    rb, ra = _ratio(zb, block), _ratio(za, block)
    gb, ga = np.sqrt(max(rb * rb - 1, 0)), np.sqrt(max(ra * ra - 1, 0))
    gap = {"before_rms_rad": rb * noise, "after_rms_rad": ra * noise, "noise_rad": noise,
           "shrink": float(1 - ga / gb) if gb > 0 else 0.0,
           "gap_sigma": float(dec.gap_sigma),
           "ljung_box_p_before": float(min(ljung_box(cw.project_out(cw.r))[1] for cw in caps)),
           "ljung_box_p_after": float(min(ljung_box(z)[1] for z in after))}

    reduced = [_params(cw.x, op) for cw in caps]
    corrected = []
    for cw, s in zip(chosen.captures, chosen.signatures):
        corrected.append(_params(cw.x + cw.state_step(cw.r - s), op))
    named = []
    if chosen.effects and dec.status == "named":
        for e, s, sh in chosen.as_effects():
            named.append({"effect": e, "in_words": in_words(e), "strength": s,
                          "shape": {n[0]: float(v) for n, v in zip(SHAPES[e], sh)}})
    probs = dict(sorted(dec.probabilities.items(), key=lambda kv: -kv[1]))
    mat = materiality(fits, ev, dec)
    result = {
        "operation": op, "breaker": br.name, "captures": len(caps),
        "sources": [cw.data.source for cw in caps],
        "status": dec.status, "effects": list(dec.effects), "named": named,
        "probabilities": probs, "rivals": dec.rivals,
        "answer": dec.answer, "answer_in_words": in_words(dec.answer),
        "answer_probability": float(dec.answer_probability), "raw_probability": float(dec.raw_probability),
        "calibration": dec.calibration,
        "absorbed": dec.absorbed, "where": where, "gap": gap,
        "materiality": mat, "discrepancy": discrepancy_report(fits, ev),
        "noise_model": {"dispersion": ev.dispersion, "ar1": ev.rho, "scale": ev.s2, "blocks": ev.n,
                        "effective_blocks": ev.n_eff, "samples_per_block": block},
        "reduced_parameters": reduced, "corrected_parameters": corrected,
        "next_measurement": next_meas,
        "holdout_shrink": holdout,
        "bic": ev.bic, "dispersion": ev.dispersion, "blocks": ev.n,
        # issue-11 keys kept for the operation page until it moves to the keys above
        "verdict": "+".join(dec.effects) if dec.status == "named" else dec.status,
        "candidates": [{"effect": k, "probability": p} for k, p in list(probs.items())[:6]],
        "how_far": None,
        "runtime_s": float(runtime_s),
        "evidence": predictive_report(scores, dec),
        "left_out": list(getattr(w, "left_out", []) or []),
    }
    result["message"] = message(result)
    result["calibration_note"] = calibration_note(dec.calibration)
    return result


def set_report(aset, fits, features: dict, scorer) -> dict:
    """The answer's set for ``--json``, the API and the card: ``set`` (hypothesis labels, pairs
    as ``a+b``, ``unexplained``), each member with its probability and how far the gap shrinks
    with it (its refit's when refitted, else the shared linear fit's), the level, and one line
    on how it was calibrated and on what."""
    members = []
    for k, lab in zip(aset.members, aset.labels):
        h = fits.hypotheses.get(k)
        if k == "none":
            shrink, how = 0.0, "nothing added"
        elif h is not None and h.effects and not h.outside:
            shrink, how = _fit_shrink(fits, h), "its joint refit"
        else:
            f = features["hypotheses"].get(k, {})
            shrink, how = f.get("shrink_all"), "the linear fit of its shapes"
        members.append({"hypothesis": lab, "in_words": in_words(k), "probability": float(aset.probabilities[k]),
                        "shrink": None if shrink is None else float(shrink), "shrink_from": how})
    return {"set": aset.labels, "set_members": members, "set_level": aset.level,
            "calibration_note": scorer_note(scorer), "calibration": "scorer"}


def _fit_shrink(fits, h) -> float:
    """1 − gap_after/gap_before of fit ``h`` against ``none`` (gap² = χ² − blocks)."""
    n = fits.windows.n
    g0 = max(fits.hypotheses["none"].chi2 - n, 0.0)
    g1 = max(h.chi2 - n, 0.0)
    return float(1.0 - np.sqrt(g1 / g0)) if g0 > 0 else 0.0


def scorer_note(scorer) -> str:
    """One line: how the set and the name were calibrated, and on what (the shipped scorer's
    provenance and its held-out figures, ``heldout`` in ``scorer.json``)."""
    pv = scorer.meta.get("provenance", {})
    protos = ", ".join(p.upper() for p in pv.get("prototypes", [])) or "?"
    kinds = ", ".join(pv.get("sensor_kinds", [])) or "?"
    held = scorer.meta.get("heldout") or {}
    cov = held.get("set_holds_truth_detectable")
    covered = (f"; leaving each prototype out, the set held the truth on {cov['k']}/{cov['n']} groups with an "
               f"effect" if cov else "")
    name = ("a single answer is named only where Learn then Test bounds wrong names at 5 % (90 % confidence)"
            if scorer.lam is not None else "no single answer is named: Learn then Test certified no threshold")
    return (f"The {100 * (1 - scorer.alpha):.0f} % set is conformal (APS) on {pv.get('rows', '?')} simulated groups "
            f"(prototypes {protos}; sensors {kinds}){covered}; {name}. Calibrated on simulations only, not on "
            f"real breakers: see docs/gap-study.md.")


def calibration_note(calibration: str) -> str:
    """One line: how the stated probabilities were calibrated and on what."""
    if calibration in (None, "", "identity"):
        return ("Probabilities: the evidence's own (each hypothesis scored on captures it was not fitted on), "
                "not calibrated: on the simulated prototypes the leave-one-prototype-out check could not "
                "certify a calibrated answer set; see docs/gap-diagnosis.md.")
    return (f"Probabilities: calibrated by the {calibration} map fitted on the simulated prototypes' study, "
            f"leaving each prototype out to check it; see docs/gap-diagnosis.md.")


ONE_CAPTURE = " One capture cannot decide between close rivals: its units of evidence are ~2 ms stretches of it."


def message(r: dict) -> str:
    """The result in one sentence: the same answer and probability as the table (with one
    capture, the caution that it cannot decide between close rivals)."""
    text = _message(r)
    if r["captures"] == 1 and r["status"] != "ambiguous":
        text += ONE_CAPTURE
    for d in r.get("left_out") or []:
        text += f" {d['source']}: {d['reason']}."
    return text


def _message(r: dict) -> str:
    g = r["gap"]
    ratio = g["before_rms_rad"] / g["noise_rad"]
    n = r["captures"]
    who = f"{n} capture{'s' if n > 1 else ''}"
    p = r["answer_probability"]
    if r["status"] == "none":
        return (f"No unmodelled effect (probability {p:.2f}) over {who}: the reduced model fits to "
                f"{ratio:.2f}× the noise floor.")
    if r["status"] == "named":
        return (f"{r['answer_in_words']} (probability {p:.2f}) explains the gap over {who}: "
                f"{g['before_rms_rad'] * 1e3:.2f} → {g['after_rms_rad'] * 1e3:.2f} mrad rms.")
    if r["status"] == "unexplained":
        pk = r["discrepancy"]["peak"]
        at = f", largest in the {pk['phase'].replace('_', ' ')} phase" if pk["phase"] else ""
        return (f"A gap of {ratio:.2f}× the noise floor over {who} that no catalogued effect describes "
                f"(outside the catalogue, probability {p:.2f}{at}).")
    one = ONE_CAPTURE + " Record more operations." if n == 1 else ""
    nm = r.get("next_measurement") or []
    nxt = f" The recording that would decide: {nm[0]['measurement']}." if nm else ""
    return f"{one_of(r)} over {who}.{one}{nxt}"


def one_of(r: dict) -> str:
    """"One of X, Y (90 %)", each member with its probability and how far the gap shrinks with it."""
    members = r.get("set_members") or [{"in_words": in_words(x["effect"]), "probability": x["probability"],
                                        "shrink": None} for x in r.get("rivals", [])]
    level = 100 * float(r.get("set_level", 0.9))

    def one(m):
        s = m.get("shrink")
        sh = "" if s is None or m["in_words"] == in_words("none") else \
            f", gap shrinks {min(100 * s, 100):.0f} %" if s < 1 else ", gap shrinks to the noise"
        return f"{m['in_words']} ({m['probability']:.2f}{sh})"

    if len(members) == 1:
        return f"{one(members[0])} ({level:.0f} % set of one, not named)"
    more = f" and {len(members) - SHOWN} more" if len(members) > SHOWN else ""
    return f"One of {', '.join(one(m) for m in members[:SHOWN])}{more} ({level:.0f} %)"


SHOWN = 5   # set members said in words; the rest are counted (all are in ``set``)


def percent(v: float) -> str:
    """A relative value in %, signed, without a "−0.0 %"."""
    x = 100.0 * float(v)
    return "0.0 %" if abs(x) < 0.05 else f"{x:+.1f} %"


def format_report(result: dict) -> str:
    g = result["gap"]
    lines = [f"hvcb diagnose: {result['operation']} on breaker {result['breaker']}, {result['captures']} capture(s)",
             f"status: {result['status']}  answer: {result['answer_in_words']} ({result['answer']}), "
             f"probability {result['answer_probability']:.3f}",
             result["message"],
             f"gap: {g['before_rms_rad'] * 1e3:.3f} -> {g['after_rms_rad'] * 1e3:.3f} mrad rms, noise "
             f"{g['noise_rad'] * 1e3:.3f} mrad, shrink {100 * g['shrink']:.0f} %",
             "where (rms/noise before -> after):"]
    for ph in result["where"]:
        lines.append(f"  {ph['phase']:<18} {ph['t0_s'] * 1e3:7.1f}-{ph['t1_s'] * 1e3:7.1f} ms  "
                     f"{ph['gap_before']:5.3f} -> {ph['gap_after']:5.3f}")
    if result.get("set"):
        lines.append(f"set: {one_of(result)}")
    lines.append("probabilities:")
    for k, p in list(result["probabilities"].items())[:6]:
        lines.append(f"  {in_words(k):<52} {p:.3f}")
    m = result["materiality"]
    lines.append(f"materiality: gap {m['gap_sigma']:.3f} σ per sample "
                 f"(95 % {m['gap_sigma_interval'][0]:.3f}-{m['gap_sigma_interval'][1]:.3f})")
    for e in m["effects"]:
        bias = ", ".join(f"{k} {percent(v)}" for k, v in e["bias"].items())
        lines.append(f"  {e['in_words']}: strength {e['strength']:.3g} (95 % {e['strength_interval'][0]:.3g}"
                     f" to {e['strength_interval'][1]:.3g}), {e['contribution_sigma']:.3f} σ unabsorbed; bias {bias}")
    for a in result["absorbed"]:
        bias = ", ".join(f"{k} {percent(v)}" for k, v in a["bias"].items())
        lines.append(f"absorbed: {in_words(a['effect'])} (typical strength) would bias {bias}")
    d = result["discrepancy"]
    if d["peak"]["phase"]:
        lines.append(f"discrepancy: ln BF {d['log_bayes_factor']:.1f}, {d['shape']}, peak {d['peak']['mrad']:.3f} mrad "
                     f"at {d['peak']['t_ms']:.1f} ms ({d['peak']['phase']})")
    for nm in result["next_measurement"][:3]:
        lines.append(f"next: {nm['measurement']} (expected ΔBIC {nm['expected_delta_bic']:.0f}, "
                     f"{' vs '.join(nm['separates'])})")
    if result.get("calibration_note"):
        lines.append(result["calibration_note"])
    lines.append(f"runtime {result['runtime_s']:.1f} s")
    return "\n".join(lines)


def plot_residuals(result: dict, before, after, t, path: str | Path) -> Path:
    """PNG of the residual [mrad] vs time, before and after the chosen correction, phases shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4))
    for i, ph in enumerate(result["where"]):
        ax.axvspan(ph["t0_s"] * 1e3, ph["t1_s"] * 1e3, color=f"C{i}", alpha=0.08)
        ax.text(0.5 * (ph["t0_s"] + ph["t1_s"]) * 1e3, 0, ph["phase"], ha="center", fontsize=7)
    ax.plot(t * 1e3, before * 1e3, lw=0.8, label="reduced model")
    if after is not None:
        ax.plot(t * 1e3, after * 1e3, lw=0.8, label="with " + (" + ".join(result["effects"]) or "nothing"))
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("residual (block mean) [mrad]")
    ax.legend()
    ax.set_title(f"{result['operation']}: {result['status']}")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
