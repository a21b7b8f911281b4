"""What the breaker page shows of a breaker diagnosis: the stored result turned into plain rows.

The diagnosis core's result is read defensively (``.get`` everywhere): a key it does not carry is
simply not shown. Both the issue-20 shape (``where``, ``probabilities``, ``next_measurement``, ...)
and the earlier one (``verdict``, ``gap.phases``, ``how_far``) are understood.
"""

from __future__ import annotations

from service.diagnosis.report import percent
from service.display import finite as _num
from service.mechanics.effects import in_words

BAR_W = 250.0  # px of the longest bar in the "where" chart




def _where(r: dict) -> list[dict]:
    """[{phase, t0_s, t1_s, before, after}] with before/after as gap ÷ noise."""
    rows = []
    if isinstance(r.get("where"), list):
        for w in r["where"]:
            if isinstance(w, dict):
                rows.append({"phase": str(w.get("phase", "?")), "t0_s": _num(w.get("t0_s")),
                             "t1_s": _num(w.get("t1_s")), "before": _num(w.get("gap_before")),
                             "after": _num(w.get("gap_after"))})
        return rows
    gap = r.get("gap") if isinstance(r.get("gap"), dict) else {}
    how = r.get("how_far") if isinstance(r.get("how_far"), dict) else {}
    after = {p.get("name"): p for p in how.get("phases_after") or [] if isinstance(p, dict)}
    for p in gap.get("phases") or []:
        if isinstance(p, dict):
            a = after.get(p.get("name"))
            rows.append({"phase": str(p.get("name", "?")), "t0_s": _num(p.get("t0_s")), "t1_s": _num(p.get("t1_s")),
                         "before": _num(p.get("ratio_to_noise")),
                         "after": _num(a.get("ratio_to_noise")) if a else None})
    return rows


def _bars(where: list[dict]) -> dict:
    """Bar geometry: widths in px on a common scale, and where the noise floor (ratio 1) falls."""
    top = max([2.0] + [v for w in where for v in (w["before"], w["after"]) if v is not None])
    scale = BAR_W / top
    for w in where:
        w["before_px"] = round(max(0.0, w["before"] or 0.0) * scale, 1)
        w["after_px"] = None if w["after"] is None else round(max(0.0, w["after"]) * scale, 1)
    return {"noise_px": round(scale, 1), "height": 40 * len(where) + 30}


def _params(reduced, corrected) -> dict:
    """Per parameter: the reduced fit and the corrected value, each the mean over the captures
    (with the captures' range), and the correction in %. From {name: value}, or a list of such
    per capture. Corrected values equal to the reduced ones (nothing named) are not repeated."""
    def as_list(x):
        if isinstance(x, dict) and x and all(isinstance(v, dict) for v in x.values()):
            return list(x.values())
        if isinstance(x, dict):
            return [x] if x else []
        if isinstance(x, list):
            return [d for d in x if isinstance(d, dict)]
        return []

    def stats(ds, name):
        vals = [v for v in (_num(d.get(name)) for d in ds) if v is not None]
        if not vals:
            return None, None, None
        return sum(vals) / len(vals), min(vals), max(vals)

    red, cor = as_list(reduced), as_list(corrected)
    if cor and red and len(cor) == len(red) and all(
            all(_num(c.get(k)) == _num(r.get(k)) for k in set(c) | set(r)) for c, r in zip(cor, red)):
        cor = []
    names: list[str] = []
    for d in red + cor:
        names += [k for k in d if k not in names]
    rows = []
    for n in names:
        rm, rlo, rhi = stats(red, n)
        cm, _, _ = stats(cor, n)
        change = (cm - rm) / abs(rm) if cm is not None and rm not in (None, 0.0) else None
        label, unit, scale = _parameter_words(n)
        rm, rlo, rhi, cm = (None if x is None else x * scale for x in (rm, rlo, rhi, cm))
        rows.append({"name": n, "label": label, "unit": unit, "reduced": rm, "lo": rlo if len(red) > 1 else None,
                     "hi": rhi if len(red) > 1 else None, "corrected": cm, "change": change,
                     "change_text": percent(change) if change is not None else ""})
    return {"rows": rows, "corrected": bool(cor), "n": len(red)}


# The reduced fit's structural values besides the parameters: (words, unit, factor from SI)
STRUCTURE = {"onset_delay_s": ("onset delay", "ms", 1e3), "alpha0": ("buffer engagement angle α₀", "rad", 1.0),
             "alpha_0": ("buffer engagement angle α₀", "rad", 1.0)}
STATUS_WORDS = {"none": "no unmodelled effect", "named": "named", "ambiguous": "ambiguous",
                "unexplained": "unexplained: nothing catalogued explains the gap", "explained": "explained",
                "partly_explained": "partly explained"}


def _parameter_words(name: str) -> tuple[str, str, float]:
    """(label, unit, factor) of a value in the parameters table: "buffer damping (DO)", "s⁻¹", 1."""
    from service.display import parameter_label, unit

    if name in STRUCTURE:
        return STRUCTURE[name]
    return parameter_label(name), unit(name), 1.0


def view(r: dict | None) -> dict | None:
    """The rows the template draws, or None without a result."""
    if not isinstance(r, dict):
        return None
    status = str(r.get("status") or r.get("verdict") or "?")
    effects = r.get("effects")
    if not isinstance(effects, list):
        v = r.get("verdict")
        effects = [v] if isinstance(v, str) and v not in ("none", "unexplained") else []
    probs = r.get("probabilities") if isinstance(r.get("probabilities"), dict) else {}
    probabilities = sorted(((str(k), _num(v)) for k, v in probs.items()), key=lambda kv: -(kv[1] or 0.0))
    rivals = [{"effect": str(x.get("effect", "?")), "probability": _num(x.get("probability"))}
              for x in r.get("rivals") or [] if isinstance(x, dict)]
    absorbed = []
    for a in r.get("absorbed") or []:
        if isinstance(a, dict):
            bias = a.get("bias", a.get("parameter_bias", a.get("parameter_shift")))
            absorbed.append({"effect": str(a.get("effect", "?")),
                             "bias": {str(k): _num(v) for k, v in bias.items()} if isinstance(bias, dict) else {}})
    gap = r.get("gap") if isinstance(r.get("gap"), dict) else {}
    how = r.get("how_far") if isinstance(r.get("how_far"), dict) else {}
    far = {"before": _num(gap.get("before_rms_rad", gap.get("rmse_rad"))),
           "after": _num(gap.get("after_rms_rad", how.get("rmse_rad_after"))),
           "noise": _num(gap.get("noise_rad")), "shrink": _num(gap.get("shrink", how.get("shrink")))}
    reduced = r.get("reduced_parameters")
    if reduced is None and isinstance(r.get("captures"), list):
        reduced = [c.get("reduced_parameters") for c in r["captures"] if isinstance(c, dict)
                   and isinstance(c.get("reduced_parameters"), dict)]
    corrected = r.get("corrected_parameters", how.get("corrected_parameters"))
    nxt = [{"measurement": str(m.get("measurement", "?")), "delta_bic": _num(m.get("expected_delta_bic")),
            "separates": [str(s) for s in m.get("separates") or []] if isinstance(m.get("separates"), list)
            else ([str(m["separates"])] if m.get("separates") else [])}
           for m in r.get("next_measurement") or [] if isinstance(m, dict)]
    where = _where(r)
    messages = [str(r["message"])] if r.get("message") else []
    messages += [str(w) for w in r.get("warnings") or [] if isinstance(w, str)]
    if r.get("calibration_note"):
        messages.append(str(r["calibration_note"]))
    for a in absorbed:
        a["bias_text"] = [f"{k} {percent(x)}" for k, x in a["bias"].items() if x is not None]
    names = {n for n, _ in probabilities} | {x["effect"] for x in rivals} | {a["effect"] for a in absorbed}
    names |= {str(e) for e in effects} | ({str(r["answer"])} if r.get("answer") else set())
    mat = r.get("materiality") if isinstance(r.get("materiality"), dict) else {}
    material = [{"effect": str(e.get("effect", "?")), "strength": _num(e.get("strength")),
                 "interval": [_num(x) for x in e.get("strength_interval") or []],
                 "contribution": _num(e.get("contribution_sigma")), "material": bool(e.get("material")),
                 "bias_text": [f"{k} {percent(x)}" for k, x in (e.get("bias") or {}).items() if _num(x) is not None]}
                for e in mat.get("effects") or [] if isinstance(e, dict)]
    names |= {m["effect"] for m in material}
    members = [{"hypothesis": str(m.get("hypothesis", "?")), "probability": _num(m.get("probability")),
                "shrink": _num(m.get("shrink"))} for m in r.get("set_members") or [] if isinstance(m, dict)]
    for m in members:
        m["name"] = "outside_catalogue" if m["hypothesis"] == "unexplained" else m["hypothesis"]
    names |= {m["name"] for m in members}
    names |= {x for m in nxt for x in m["separates"]}
    for w in where:
        w["phase_words"] = w["phase"].replace("_", " ")
    disc = r.get("discrepancy") if isinstance(r.get("discrepancy"), dict) else {}
    peak = disc.get("peak") if isinstance(disc.get("peak"), dict) else {}
    return {"status": status, "status_words": STATUS_WORDS.get(status, status.replace("_", " ")),
            "effects": [str(e) for e in effects], "probabilities": probabilities,
            "answer": str(r["answer"]) if r.get("answer") else None,
            "answer_probability": _num(r.get("answer_probability")),
            "raw_probability": _num(r.get("raw_probability")),
            "words": {n: in_words(n) for n in names},
            "gap_sigma": _num(mat.get("gap_sigma")),
            "gap_interval": [_num(x) for x in mat.get("gap_sigma_interval") or []],
            "material": material,
            "discrepancy": {"phase": peak.get("phase"), "t_ms": _num(peak.get("t_ms")), "mrad": _num(peak.get("mrad")),
                            "shape": disc.get("shape"), "log_bf": _num(disc.get("log_bayes_factor"))}
            if peak.get("phase") else None,
            "set": members, "set_level": _num(r.get("set_level")),
            "rivals": rivals, "absorbed": absorbed, "far": far, "where": where, "bars": _bars(where),
            "params": _params(reduced, corrected), "next": nxt, "messages": messages,
            "captures": len(r["captures"]) if isinstance(r.get("captures"), list) else None}
