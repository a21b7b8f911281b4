"""Training and calibrating the scorer on the corpus (issue 48 items 2–3). Pure functions of
the corpus rows (``corpus.rows``), no I/O.

* ``dataset``: per labelled row its hypotheses' feature matrix and the index of its label
  (``unexplained`` is ``outside_catalogue``); a row without a label or whose label is none of its
  hypotheses is left out with its reason (counted).
* ``fit``: the conditional logit (``diagnosis.scorer``) by L-BFGS on the mean negative log
  likelihood plus ``L2``/2·‖w‖² on standardised features. ``L2`` = 1e-2 was set before any
  held-out figure was seen and is not tuned.
* ``crossval``: leave one group out (a prototype, or a sensor kind): each held-out row's
  probabilities come from a scorer fitted without its group.
* ``aps_quantile`` / ``aps_set``: the answer's 90 % set, adaptive prediction sets (Romano, Sesia
  & Candès 2020, "Classification with valid and adaptive coverage", NeurIPS 33) with their
  randomisation fixed at U = 0: the score of a row is the probability mass of the hypotheses
  ranked strictly above its truth; q̂ its ⌈(n + 1)(1 − α)⌉-th smallest over the calibration rows;
  the set, every hypothesis whose mass above it is at most q̂ (the most probable always). Split
  conformal's coverage holds for any fixed score, so for this one too; U = 0 gives the smallest
  of the randomised sets (the U = 1 form, "until the mass reaches q̂", over-covers: 0.97 for a
  0.9 target on a 6-class test).
* ``name_threshold``: Learn then Test (Angelopoulos, Bates, Candès, Jordan & Lei 2021,
  arXiv:2110.01052) for naming a set of one: the answer is a name when its probability is at
  least λ; the loss is a wrong name (a set of one that is not the truth); λ from 0.999 down,
  each tested by the Hoeffding–Bentkus p-value of H0: R(λ) > α (``risk.hb_pvalue``) in a fixed
  sequence, stopping at the first p > δ; the lowest λ that passed is kept (none passed: nothing
  is named).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize

from ...diagnosis.scorer import FEATURES, OUTSIDE, Scorer, design, softmax_rows
from .risk import hb_pvalue

L2 = 1e-2
ALPHA_SET = 0.1
ALPHA_NAME = 0.05
DELTA = 0.1
LAMBDAS = tuple(np.round(np.concatenate([[0.999, 0.995, 0.99, 0.98], np.arange(0.97, 0.49, -0.01)]), 3))


def hyp_label(label: str) -> str:
    return OUTSIDE if label == "unexplained" else label


def dataset(rows):
    """(items, left out): items are dicts with the row, its hypotheses' names and matrix and the
    label's index."""
    items, left = [], []
    for r in rows:
        why = r.get("error") or r.get("failed")
        if why:
            left.append((r, f"no diagnosis: {why}"))
            continue
        if r.get("label") is None:
            left.append((r, f"no label: {r.get('label_reason')}"))
            continue
        if not r.get("features"):
            left.append((r, "no features"))
            continue
        names, X = design(r["features"])
        lab = hyp_label(r["label"])
        if lab not in names:
            left.append((r, f"its label {r['label']} is none of its hypotheses"))
            continue
        items.append({"row": r, "names": names, "X": X, "y": names.index(lab)})
    return items, left


def fit(items, l2: float | None = None, meta=None) -> Scorer:
    """The conditional logit fitted on ``items`` (module docstring); ``l2`` default ``L2``."""
    l2 = L2 if l2 is None else l2
    Xall = np.vstack([it["X"] for it in items])
    mean = Xall.mean(axis=0)
    scale = Xall.std(axis=0)
    scale = np.where(scale > 1e-9, scale, 1.0)
    Zs = [(it["X"] - mean) / scale for it in items]
    ys = [it["y"] for it in items]
    n = len(items)

    def f(w):
        nll = 0.0
        grad = np.zeros_like(w)
        for Z, y in zip(Zs, ys):
            u = Z @ w
            m = u.max()
            p = np.exp(u - m)
            s = p.sum()
            p /= s
            nll += -(u[y] - m - math.log(s))
            grad += Z.T @ p - Z[y]
        return nll / n + 0.5 * l2 * float(w @ w), grad / n + l2 * w

    res = minimize(f, np.zeros(len(FEATURES)), jac=True, method="L-BFGS-B", options={"maxiter": 500})
    return Scorer(res.x, mean, scale, dict(meta or {}, l2=l2, converged=bool(res.success), train_rows=n))


def probabilities(scorer: Scorer, item) -> np.ndarray:
    return softmax_rows(scorer.utilities(item["X"]))


def crossval(items, key) -> list:
    """Each item's probabilities from the scorer fitted without its ``key(row)`` group."""
    groups = sorted({key(it["row"]) for it in items})
    out = [None] * len(items)
    for g in groups:
        train = [it for it in items if key(it["row"]) != g]
        if not train:
            continue
        sc = fit(train)
        for i, it in enumerate(items):
            if key(it["row"]) == g:
                out[i] = probabilities(sc, it)
    return out


def aps_score(p: np.ndarray, y: int) -> float:
    """The probability mass ranked strictly above the truth ``y``."""
    order = np.argsort(-p, kind="stable")
    rank = int(np.nonzero(order == y)[0][0])
    return float(np.sum(p[order[:rank]]))


def aps_quantile(scores, alpha: float = ALPHA_SET) -> float:
    s = np.sort(np.asarray(scores, float))
    k = math.ceil((s.size + 1) * (1.0 - alpha))
    return 1.0 if k > s.size else float(s[k - 1])


def aps_set(names, p: np.ndarray, qhat: float) -> list:
    """Every hypothesis whose probability mass ranked above it is at most ``qhat``."""
    order = np.argsort(-p, kind="stable")
    out, mass = [], 0.0
    for j in order:
        if mass > qhat + 1e-12:
            break
        out.append(names[j])
        mass += float(p[j])
    return out


def name_threshold(probs, ys, alpha: float = ALPHA_NAME, delta: float = DELTA):
    """The lowest λ of the fixed sequence whose wrong-name risk passes (module docstring), or
    None; with the p-values tested."""
    top = np.array([float(np.max(p)) for p in probs])
    right = np.array([int(np.argmax(p)) == y for p, y in zip(probs, ys)])
    n = top.size
    kept, tested = None, []
    for lam in LAMBDAS:
        loss = (top >= lam) & ~right
        pv = hb_pvalue(float(loss.mean()) if n else 0.0, n, alpha)
        tested.append({"lambda": float(lam), "risk": float(loss.mean()) if n else 0.0, "p": pv,
                       "named": int((top >= lam).sum())})
        if pv > delta:
            break
        kept = float(lam)
    return kept, tested
