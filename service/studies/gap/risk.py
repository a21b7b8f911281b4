"""Naming under risk control and the answer as a set (issue 42 item 4), leave one prototype out.

Labels. A group's true label is ``none`` (healthy, or an effect the oracle finds undetectable:
Δχ² < 100, the gap within the noise), the effect's name (a detectable single effect), the pair
``a+b`` (two effects) or ``unexplained`` (a detectable effect outside the catalogue). The
diagnosis's probabilities are read over the same labels (``outside_catalogue`` → unexplained).

**The set: split conformal** (Vovk, Gammerman & Shafer 2005; the "least ambiguous set" score of
Sadinle, Lei & Wasserman 2019, JASA 114:223; Angelopoulos & Bates 2021, *A gentle
introduction to conformal prediction*, §1): score s = 1 − p(true label) on the calibration
groups, q̂ their ⌈(n + 1)(1 − α)⌉-th smallest, and the set {y : 1 − p(y) ≤ q̂}. Under
exchangeability of the held-out prototype's groups with the calibration groups it holds the
truth with probability ≥ 1 − α; across prototypes that is an assumption the held-out figures test.

**The name: Learn then Test** (Angelopoulos, Bates, Candès, Jordan & Lei 2021, *Learn then
Test: calibrating predictive algorithms to achieve risk control*, arXiv:2110.01052). A threshold
λ = (margin of the top label's probability over the best rival, share of the above-noise gap
its fit explains) names the top label when both are reached and, for an effect, the share is at
least ½ ("material or nothing"). The loss is a wrong name; for each λ the Hoeffding–Bentkus
p-value of H0: R(λ) > α (Bates, Angelopoulos, Lei, Malik & Jordan 2021, *Distribution-free,
risk-controlling prediction sets*, JACM 68:43, §3.1.2) is tested in a fixed sequence from the
strictest λ down, stopping at the first p > δ; every λ before it controls P(R > α) ≤ δ. Of
those, the one that names most often on the calibration groups is kept; none → nothing is named
(the answer is the set). Pure functions, no I/O.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import binom

DETECTABLE = 100.0                # the former fixed threshold; a row's own is ``labels.threshold``
MATERIAL = 0.5                    # an effect explaining less than half of the gap is never named
MARGINS = (0.99, 0.95, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1, 0.05, 0.0)
SHARES = (0.9, 0.8, 0.7, 0.6, 0.5)


def true_label(row: dict) -> str:
    """The label a group should get (module docstring)."""
    truth = sorted(row.get("truth") or [])
    from .labels import threshold

    detectable = float((row.get("oracle") or {}).get("delta_chi2", 0.0) or 0.0) >= threshold(row)[0]
    if row.get("outside"):
        return "unexplained" if detectable else "none"
    if not truth:
        return "none"
    if len(truth) == 2:
        return "+".join(truth)
    return truth[0] if detectable else "none"


def label_probabilities(row: dict) -> dict:
    """The diagnosis's probabilities over the labels (``outside_catalogue`` → unexplained)."""
    out = {}
    for k, v in (row.get("probabilities") or {}).items():
        out["unexplained" if k == "outside_catalogue" else k] = float(v)
    return out


def conformal_quantile(scores, alpha: float) -> float:
    """q̂: the ⌈(n + 1)(1 − α)⌉-th smallest of the calibration scores (∞ when n is too small)."""
    s = np.sort(np.asarray(scores, float))
    n = s.size
    k = math.ceil((n + 1) * (1.0 - alpha))
    return float("inf") if k > n else float(s[k - 1])


def prediction_set(probs: dict, qhat: float) -> list:
    """The labels whose score 1 − p is at most q̂, most probable first (never empty: the top
    label when nothing qualifies)."""
    ranked = sorted(probs.items(), key=lambda kv: -kv[1])
    out = [k for k, p in ranked if 1.0 - p <= qhat]
    return out or [ranked[0][0]]


def hb_pvalue(risk_hat: float, n: int, alpha: float) -> float:
    """Hoeffding–Bentkus p-value of H0: R > α from the empirical risk of n losses in [0, 1]."""
    if n <= 0:
        return 1.0
    r = min(max(risk_hat, 0.0), 1.0)

    def h1(a, b):
        if a <= 0:
            return -math.log(1 - b)
        if a >= 1:
            return -math.log(b)
        return a * math.log(a / b) + (1 - a) * math.log((1 - a) / (1 - b))

    hoeff = math.exp(-n * h1(min(r, alpha), alpha))
    bentkus = math.e * float(binom.cdf(math.ceil(n * r), n, alpha))
    return float(min(hoeff, bentkus, 1.0))


def names(row: dict, margin: float, share: float):
    """The name the rule (margin, share) gives ``row``, or None."""
    probs = label_probabilities(row)
    if not probs:
        return None
    ranked = sorted(probs.items(), key=lambda kv: -kv[1])
    top, p1 = ranked[0]
    p2 = ranked[1][1] if len(ranked) > 1 else 0.0
    if p1 - p2 < margin:
        return None
    if top not in ("none", "unexplained"):
        explained = float((row.get("gap") or {}).get("shrink", 0.0) or 0.0)
        if explained < max(share, MATERIAL):
            return None
    return top


def thresholds_sequence():
    """λ from the strictest to the least strict (the fixed sequence of the test)."""
    return [(m, s) for m in MARGINS for s in SHARES]


def learn_then_test(rows, alpha: float = 0.05, delta: float = 0.1) -> dict:
    """The naming thresholds chosen on ``rows`` (module docstring). Returns {"margin", "share"}
    or None for both when no λ is certified, with the sequence's p-values."""
    n = len(rows)
    labels = [true_label(r) for r in rows]
    tested, valid = [], []
    for m, s in thresholds_sequence():
        given = [names(r, m, s) for r in rows]
        wrong = sum(1 for g, y in zip(given, labels) if g is not None and g != y)
        p = hb_pvalue(wrong / n if n else 1.0, n, alpha)
        tested.append({"margin": m, "share": s, "wrong": wrong, "named": sum(g is not None for g in given),
                       "p_value": p})
        if p > delta:
            break
        valid.append(tested[-1])
    best = max(valid, key=lambda t: (t["named"], -t["margin"], -t["share"])) if valid else None
    if best is None or best["named"] == 0:       # certified only by naming nothing: nothing is named
        return {"margin": None, "share": None, "n": n, "tested": tested}
    return {"margin": best["margin"], "share": best["share"], "n": n, "tested": tested}


def answer(row: dict, rule: dict, qhat: float) -> dict:
    """The answer to one group: the name when the rule names, else the set."""
    probs = label_probabilities(row)
    s = prediction_set(probs, qhat)
    name = names(row, rule["margin"], rule["share"]) if rule.get("margin") is not None else None
    return {"name": name, "set": [name] if name else s}


def lopo(rows, alpha_set: float = 0.1, alpha_name: float = 0.05, delta: float = 0.1, key: str = "prototype"):
    """Leave one prototype out: for each prototype, the set's q̂ and the naming rule chosen on the
    others' groups, applied to its own. Returns {prototype: {"rule", "qhat", "answers": [(row,
    answer, label)]}}."""
    protos = sorted({r[key] for r in rows})
    out = {}
    for p in protos:
        cal = [r for r in rows if r[key] != p]
        test = [r for r in rows if r[key] == p]
        scores = [1.0 - label_probabilities(r).get(true_label(r), 0.0) for r in cal]
        qhat = conformal_quantile(scores, alpha_set)
        rule = learn_then_test(cal, alpha_name, delta)
        out[p] = {"rule": rule, "qhat": qhat, "n_calibration": len(cal),
                  "answers": [(r, answer(r, rule, qhat), true_label(r)) for r in test]}
    return out


def wilson(k: int, n: int, z: float = 1.96):
    """Wilson score interval of k/n."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (max(0.0, c - h), min(1.0, c + h))


def figures(answers) -> dict:
    """The issue's figures over one prototype's answers [(row, answer, label)]: (k, n) each."""
    def frac(pred, among):
        sel = [a for a in answers if among(a)]
        return (sum(1 for a in sel if pred(a)), len(sel))

    from .labels import threshold

    def detectable(a):
        return (float((a[0].get("oracle") or {}).get("delta_chi2", 0.0) or 0.0) >= threshold(a[0])[0]
                and a[2] != "none")

    sizes = [len(a[1]["set"]) for a in answers if detectable(a)]
    return {
        "wrong_names": frac(lambda a: a[1]["name"] is not None and a[1]["name"] != a[2], lambda a: True),
        "healthy_none": frac(lambda a: a[1]["set"] == ["none"], lambda a: not a[0].get("truth") and not a[0].get("outside")),
        "names_right": frac(lambda a: a[1]["name"] == a[2], lambda a: a[1]["name"] is not None),
        "set_holds_truth_detectable": frac(lambda a: a[2] in a[1]["set"], detectable),
        "mean_set_size_detectable": float(np.mean(sizes)) if sizes else None,
        "named_detectable": frac(lambda a: a[1]["name"] is not None, detectable),
        "two_effects": frac(lambda a: a[2] in a[1]["set"], lambda a: len(a[0].get("truth") or []) == 2),
    }
