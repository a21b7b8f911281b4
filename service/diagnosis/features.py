"""Stage 3 — the features of every hypothesis (issue 48 item 2), the scorer's input.

The evidence stage (``predictive``) leaves, per capture, the pre-whitened residual with each
capture's nuisance projected out and each hypothesis's columns. From them, for **every**
hypothesis (``none``, each family, every pair of families, ``outside_catalogue``), in closed form:

* ``elpd``: its leave-one-capture-out log predictive density relative to ``none`` [nats] (the
  evidence stage's, which for its leading hypotheses is the better of the reduced fit's profile
  and its own exact refit's), and per unit;
* ``shrink``: per held-out unit, 1 − gap_after/gap_before of that unit predicted from the
  others' shared fit (gap² = χ² − rows, its rows' noise removed), and ``shrink_all``, the same
  of the fit on every unit; the per-unit values say whether the captures agree;
* ``where``: where in the motion the fitted shape acts: the centroid and the spread of its
  energy in the group's normalised motion time, as shares of the scored span [0, 1];
* ``dim``: its shared coefficients.

Per group: ``rows`` and ``units``, ``chi2`` of ``none`` (Σ of the projected residual's squares),
its ``gap_sigma`` = (χ² − rows)/√(2·rows) (the gap above the noise, in the noise's own sd),
``whiteness`` (the mean Ljung–Box Q per lag of each capture's residual: ≈ 1 when white) and
``where`` of the residual's excess energy.

Pure functions of arrays; the scorer (``scorer``) turns these into its feature vectors.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from .whiteness import LAGS, ljung_box


def loo_lpd(units, names) -> np.ndarray:
    """Per unit the LOO log predictive density of hypothesis ``names`` (a tuple of column
    groups), minus that of ``none`` (closed form, see the module docstring)."""
    Xs = [np.column_stack([cols[n] for n in names]) if names else np.zeros((r.size, 0)) for r, cols in units]
    k = Xs[0].shape[1]
    if k == 0:
        return np.zeros(len(units))
    A = sum(X.T @ X for X in Xs)
    b = sum(X.T @ r for X, (r, _) in zip(Xs, units))
    n = sum(r.size for r, _ in units)
    M = A * (1.0 + 1.0 / n) + 1e-12 * np.trace(A) / k * np.eye(k)   # Zellner g = n
    _, ldM = np.linalg.slogdet(M)
    out = np.empty(len(units))
    for j, (X, (r, _)) in enumerate(zip(Xs, units)):
        XtX, Xtr = X.T @ X, X.T @ r
        Mj = M - XtX
        m = np.linalg.solve(Mj, b - Xtr)
        e = r - X @ m
        Xte = X.T @ e
        quad = float(e @ e - Xte @ np.linalg.solve(M, Xte))
        sign, ldMj = np.linalg.slogdet(Mj)
        if sign <= 0:
            out[j] = -np.inf
            continue
        out[j] = -0.5 * (quad - float(r @ r)) - 0.5 * (ldM - ldMj)
    return out


def loo_detail(units, names, dof):
    """Per unit: (held-out χ² before, after the others' shared fit, its noise's degrees of
    freedom ``dof``) of hypothesis ``names`` (column groups), by the same Zellner-prior posterior
    mean as ``loo_lpd``."""
    Xs = [np.column_stack([cols[n] for n in names]) if names else np.zeros((r.size, 0)) for r, cols in units]
    before = np.array([float(r @ r) for r, _ in units])
    rows = np.asarray(dof, float)
    k = Xs[0].shape[1]
    if k == 0:
        return before, before.copy(), rows
    A = sum(X.T @ X for X in Xs)
    b = sum(X.T @ r for X, (r, _) in zip(Xs, units))
    n = float(sum(r.size for r, _ in units))
    M = A * (1.0 + 1.0 / n) + 1e-12 * np.trace(A) / k * np.eye(k)
    after = np.empty(len(units))
    for j, (X, (r, _)) in enumerate(zip(Xs, units)):
        m = np.linalg.lstsq(M - X.T @ X, b - X.T @ r, rcond=None)[0]
        e = r - X @ m
        after[j] = float(e @ e)
    return before, after, rows


def shrink(before: float, after: float, dof: float) -> float:
    """The share of the gap removed: (χ²_before − χ²_after)/gap, gap = χ²_before − dof above the
    noise's degrees of freedom, at least the noise's own sd √(2·dof) (so a gap within the noise
    gives a small share, not a ratio of two noises); > 1 when the fit also takes noise, < 0 when
    the held-out unit is predicted worse than by the reduced model."""
    gap = max(before - dof, np.sqrt(2.0 * max(dof, 1.0)))
    return float((before - after) / gap)


def fitted_where(caps, names, lo: float, hi: float) -> tuple:
    """Centroid and sd of the energy of the shared fit of ``names`` over the captures, as shares
    of the span [lo, hi] of normalised motion time."""
    Xs = [np.column_stack([c.cols[n] for n in names]) for c in caps]
    A = sum(X.T @ X for X in Xs)
    b = sum(X.T @ c.r for X, c in zip(Xs, caps))
    beta = np.linalg.lstsq(A, b, rcond=None)[0]
    return energy_where([X @ beta for X in Xs], [c.t_rel for c in caps], lo, hi)


def energy_where(signals, times, lo, hi) -> tuple:
    w = np.concatenate([np.asarray(s, float) ** 2 for s in signals])
    u = (np.concatenate(times) - lo) / max(hi - lo, 1e-12)
    tot = float(w.sum())
    if not np.isfinite(tot) or tot <= 0:
        return 0.5, 0.0
    c = float(w @ u / tot)
    return c, float(np.sqrt(max(float(w @ (u - c) ** 2) / tot, 0.0)))


def collect(caps, units, lpd: dict, dims: dict, hyps: dict, singles) -> dict:
    """Every hypothesis's features and the group's (module docstring). ``hyps``: name → column
    groups of the hypotheses the evidence stage scored (``lpd`` and ``dims`` by name); every pair
    of ``singles`` it did not score is scored here on the reduced fit's profile."""
    lo = min(float(c.t_rel[0]) for c in caps)
    hi = max(float(c.t_rel[-1]) for c in caps)
    table = dict(hyps)
    for a, b in combinations(sorted(singles), 2):
        name = f"{a}+{b}"
        if name not in table:
            table[name] = (a, b)
    dof = unit_dof(caps, units)
    out = {}
    for name, cols in table.items():
        if name == "outside_catalogue":
            continue
        v = lpd.get(name)
        if v is None:
            v = loo_lpd(units, cols)
        before, after, rows = loo_detail(units, cols, dof)
        per = [shrink(b0, a0, n0) for b0, a0, n0 in zip(before, after, rows)]
        c, s = fitted_where(caps, cols, lo, hi) if cols else (0.5, 0.0)
        k = int(dims.get(name, sum(caps[0].cols[n].shape[1] for n in cols)))
        fa = sum(float(np.sum(r ** 2)) for r, _ in units)
        out[name] = {"elpd": float(np.sum(v)), "lpd": [float(x) for x in v], "dim": k,
                     "shrink": per, "shrink_all": _shrink_all(caps, cols, fa, float(np.sum(dof))),
                     "where": c, "where_sd": s}
    if "outside_catalogue" in lpd and lpd["outside_catalogue"] is not None:
        v = lpd["outside_catalogue"]
        out["outside_catalogue"] = {"elpd": float(np.sum(v)), "lpd": [float(x) for x in v],
                                    "dim": int(dims.get("outside_catalogue", 0))}
    n = float(np.sum(dof))
    chi2 = float(sum(float(r @ r) for r, _ in units))
    q = [ljung_box(c.r)[0] / LAGS for c in caps]
    ex = [np.maximum(c.r ** 2 - 1.0, 0.0) for c in caps]
    wc, ws = energy_where([np.sqrt(e) for e in ex], [c.t_rel for c in caps], lo, hi)
    group = {"rows": float(sum(r.size for r, _ in units)), "dof": n, "units": len(units), "captures": len(caps), "chi2": chi2,
             "gap_sigma": float((chi2 - n) / np.sqrt(2.0 * n)) if n > 0 else 0.0,
             "whiteness": float(np.mean(q)), "where": wc, "where_sd": ws}
    return {"group": group, "hypotheses": out}


def unit_dof(caps, units) -> np.ndarray:
    """Each unit's noise degrees of freedom: its rows less its share of its capture's nuisance
    columns (projected out)."""
    if len(units) == len(caps) and all(r.size == c.r.size for (r, _), c in zip(units, caps)):
        return np.array([c.r.size - c.Qw.shape[1] for c in caps], float)
    c = caps[0]
    return np.array([r.size * (1.0 - c.Qw.shape[1] / max(c.r.size, 1)) for r, _ in units], float)


def _shrink_all(caps, cols, before: float, dof: float) -> float:
    if not cols:
        return 0.0
    X = [np.column_stack([c.cols[n] for n in cols]) for c in caps]
    A = sum(x.T @ x for x in X)
    b = sum(x.T @ c.r for x, c in zip(X, caps))
    beta = np.linalg.lstsq(A, b, rcond=None)[0]
    after = sum(float(np.sum((c.r - x @ beta) ** 2)) for x, c in zip(X, caps))
    return shrink(before, after, dof)
