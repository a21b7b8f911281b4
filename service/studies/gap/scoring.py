"""The gap study's figures, exactly as issue 29's Acceptance states them.

A row is one diagnosed group: ``truth`` (catalogued effect names, sorted), ``outside`` (an
effect outside the catalogue), the diagnosis's ``status``, ``effects`` (named), ``answer``,
``answer_probability`` (stated), ``rivals``, ``absorbed``, and the oracle's verdict ``oracle``
(:mod:`.oracle`: ``detectable``, ``bias``).

Rules (each a function of one row, so that each can fail on its own):

* top-1 on detectable single-effect groups: ``named`` with exactly the truth;
* healthy → ``none``;
* wrong names, over all groups: a named effect that is not in the truth (a rival listed
  beside it does not excuse it);
* two effects: both named, or ``ambiguous`` with both among the rivals;
* outside the catalogue → ``unexplained``;
* undetectable single-effect groups → ``none``, the effect in ``absorbed``, its stated bias
  agreeing with the oracle's (:func:`bias_agrees`; counted where the generator wrote the healthy
  twin that gives the true bias);
* right (for calibration): the answer is what the Acceptance expects: the truth, ``none`` on
  healthy and on undetectable single-effect groups, ``unexplained`` outside the catalogue.

Every fraction carries its Wilson 95 % interval: at n ≈ 20 a group more or less moves a
fraction by 5 points, and the interval says how far the data can speak.
"""

from __future__ import annotations

import math

import numpy as np

# The development prototypes (the method may be built on them); any other is held out.
DEVELOPMENT = ("a", "b", "c", "d")   # D, seen in round 4, is a development prototype since issue 36

Z95 = 1.959963984540054
BINS = (0.0, 0.5, 0.7, 0.9, 0.99, 1.0)
# the diagnosis states an absorbed effect's bias at its realistic strength; the groups' strengths
# are 0.7–1.2 of it, so the oracle's bias (at the true strength) is 0.7–1.2 × the stated one when
# the shapes agree: a factor 2 either way leaves room for the shape, not for a wrong sign
BIAS_FACTOR = 2.0
OUTSIDE_ANSWERS = ("outside_catalogue", "unexplained")


def wilson(k: int, n: int, z: float = Z95) -> tuple | None:
    """Wilson score interval of k successes in n trials (None when n = 0)."""
    if n == 0:
        return None
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (max(0.0, c - h), min(1.0, c + h))


def frac(rows, rule) -> dict:
    """k of n rows pass ``rule``, the fraction and its Wilson interval."""
    hits = [bool(rule(r)) for r in rows]
    k, n = int(sum(hits)), len(hits)
    return {"k": k, "n": n, "fraction": k / n if n else None, "wilson95": wilson(k, n)}


def is_single(r) -> bool:
    return len(r["truth"]) == 1 and not r["outside"]


def is_healthy(r) -> bool:
    return not r["truth"] and not r["outside"]


def detectable(r) -> bool:
    return bool(r.get("oracle", {}).get("detectable"))


def top1(r) -> bool:
    return r["status"] == "named" and set(r["effects"]) == set(r["truth"])


def wrong(r) -> bool:
    return any(e not in r["truth"] for e in r["effects"])


def rival_names(r) -> set:
    names = set()
    for rv in r.get("rivals") or []:
        names |= set(str(rv["effect"]).split("+"))
    return names


def both(r) -> bool:
    return top1(r) or (r["status"] == "ambiguous" and set(r["truth"]) <= rival_names(r))


def bias_agrees(stated: dict, truth: dict, factor: float = BIAS_FACTOR) -> bool:
    """The stated relative bias agrees with the oracle's on the parameter the oracle finds most
    biased (τ left out: its relative shift is of a fraction of a millisecond): same sign, and
    within ``factor`` either way."""
    keys = [k for k in truth if k in stated and k != "tau"]
    if not keys:
        return False
    k = max(keys, key=lambda q: abs(truth[q]))
    t, s = truth[k], stated[k]
    return t * s > 0 and 1 / factor <= s / t <= factor


def absorbed_listed(r) -> bool:
    """``none`` with the true effect in ``absorbed`` (the bias not checked)."""
    return r["status"] == "none" and any(a["effect"] in r["truth"] for a in r.get("absorbed") or [])


def has_true_bias(r) -> bool:
    """The oracle knows the effect's true bias (the generator wrote the healthy twin)."""
    return bool(r.get("oracle", {}).get("bias"))


def absorbed_ok(r) -> bool:
    """``none``, the true effect in ``absorbed``, its stated bias agreeing with the oracle's."""
    if r["status"] != "none":
        return False
    bias = r.get("oracle", {}).get("bias") or {}
    for a in r.get("absorbed") or []:
        if a["effect"] in r["truth"]:
            return bias_agrees(a.get("bias") or a.get("parameter_bias") or {}, bias)
    return False


def expected_answer(r) -> str:
    """What the Acceptance expects the answer to be."""
    if r["outside"]:
        return "unexplained"
    if not r["truth"] or (is_single(r) and not detectable(r)):
        return "none"
    return "+".join(sorted(r["truth"]))


def right(r) -> bool:
    want, got = expected_answer(r), r["answer"]
    if want == "unexplained":
        return got in OUTSIDE_ANSWERS or r["status"] == "unexplained"
    return got == want


def score(rows) -> dict:
    """The Acceptance's figures over one prototype's diagnosed groups."""
    ok = [r for r in rows if "error" not in r]
    singles = [r for r in ok if is_single(r)]
    det = [r for r in singles if detectable(r)]
    hi = [r for r in ok if r["answer_probability"] >= 0.9]
    return {
        "groups": len(rows), "errors": len(rows) - len(ok),
        "oracle_detectable": {"k": len(det), "n": len(singles)},
        "top1_detectable": frac(det, top1),
        "top1_all_single": frac(singles, top1),
        "top1_detectable_1000": frac([r for r in singles if oracle_delta(r) >= STRONG_CHI2], top1),
        "shrink_ratio": shrink_ratios([r for r in ok if top1(r) or (len(r["truth"]) == 2 and r["status"] == "named"
                                                                  and set(r["effects"]) == set(r["truth"]))]),
        "none_on_healthy": frac([r for r in ok if is_healthy(r)], lambda r: r["status"] == "none"),
        "wrong_names": frac(ok, wrong),
        "two_effect_both": frac([r for r in ok if len(r["truth"]) == 2], both),
        "outside_unexplained": frac([r for r in ok if r["outside"]], lambda r: r["status"] == "unexplained"),
        "undetectable_none_absorbed_listed": frac([r for r in singles if not detectable(r)], absorbed_listed),
        "undetectable_none_absorbed": frac([r for r in singles if not detectable(r) and has_true_bias(r)],
                                           absorbed_ok),
        "undetectable_none": frac([r for r in singles if not detectable(r)], lambda r: r["status"] == "none"),
        "stated_ge_0_9_right": frac(hi, right),
        "status_counts": {s: sum(r["status"] == s for r in ok) for s in ("none", "named", "ambiguous", "unexplained")},
    }


STRONG_CHI2 = 1000.0   # issue 36: top-1 ≥ 90 % on groups whose oracle Δχ² ≥ 1,000
SHRINK_FACTOR = 1.5    # issue 36: the stated reduction of the gap within a factor 1.5 of the oracle's


def oracle_delta(r) -> float:
    d = r.get("oracle", {}).get("delta_chi2")
    return float(d) if d is not None else float("-inf")


def stated_reduction(r) -> float | None:
    """The diagnosis's stated reduction of the gap as a Δχ² over the group's samples:
    (before² − after²)/noise² per sample × samples (``gap`` and ``blocks``, ``noise_model``)."""
    g, nb = r.get("gap"), r.get("blocks")
    block = (r.get("noise_model") or {}).get("samples_per_block")
    if not g or not nb or not block or not g.get("noise_rad"):
        return None
    rb, ra = g["before_rms_rad"] / g["noise_rad"], g["after_rms_rad"] / g["noise_rad"]
    return float((rb * rb - ra * ra) * nb * block)


def shrink_ratios(rows) -> dict:
    """Per correctly named group: stated reduction / the oracle's Δχ²; the count within a factor
    SHRINK_FACTOR, with its Wilson interval."""
    ratios = []
    for r in rows:
        st, od = stated_reduction(r), oracle_delta(r)
        if st is not None and od > 0:
            ratios.append(st / od)
    within = [1.0 / SHRINK_FACTOR <= x <= SHRINK_FACTOR for x in ratios]
    k, n = int(sum(within)), len(within)
    return {"ratios": [float(x) for x in ratios], "k": k, "n": n, "fraction": k / n if n else None,
            "wilson95": wilson(k, n), "median": float(np.median(ratios)) if ratios else None}


def reliability(probabilities, hits, bins=BINS) -> list:
    """Stated probability in bins vs the fraction right, with Wilson intervals (the last bin
    closed at 1)."""
    p = np.asarray(probabilities, float)
    h = np.asarray(hits, bool)
    out = []
    for i, (lo, hi) in enumerate(zip(bins[:-1], bins[1:])):
        sel = (p >= lo) & ((p <= hi) if i == len(bins) - 2 else (p < hi))
        k, n = int(h[sel].sum()), int(sel.sum())
        out.append({"from": lo, "to": hi, "n": n, "mean_stated": float(p[sel].mean()) if n else None,
                    "fraction_right": k / n if n else None, "wilson95": wilson(k, n)})
    return out


# The Acceptance's targets: (figure, comparison, bound)
TARGETS = {"top1_detectable": (">=", 0.75), "top1_detectable_1000": (">=", 0.90), "none_on_healthy": (">=", 0.90), "wrong_names": ("<=", 0.05),
           "two_effect_both": (">=", 7 / 8), "outside_unexplained": (">=", 0.90),
           "stated_ge_0_9_right": (">=", 0.90)}


def meets(figure: dict, target) -> bool | None:
    """Whether a fraction meets its target (None when there is nothing to count)."""
    if figure["fraction"] is None:
        return None
    op, bound = target
    return figure["fraction"] >= bound if op == ">=" else figure["fraction"] <= bound
