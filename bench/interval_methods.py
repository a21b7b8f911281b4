"""The covariance methods compared on the same fits (issue 44 item 1): bench/interval_coverage.py
--dump keeps each fit's Jacobian J and residual e at the reported estimate; here each method's
standard errors are computed from them and judged like the bench judges the service's own:
coverage of the mean estimate by the stated 95 % interval, mean width over the estimates' spread,
mean width over today's (white).

- white: σ²(JᵀJ)⁻¹, σ from the idle samples (the interval before issue 44);
- nw_andrews: Newey–West (1987) sandwich, Bartlett weights, Andrews (1991) AR(1) plug-in bandwidth;
- nw_prewhite: the same after VAR(1) prewhitening (Andrews & Monahan 1992);
- ar_bic: the service's (service.estimation.uncertainty): AR(p) residual model, p by BIC;
- ar_aic: the same with p by AIC.
All floored at white. Writes bench/results/interval_methods.json.

    .venv/bin/python bench/interval_methods.py /tmp/ic40.pkl
"""

from __future__ import annotations

import json
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from service.estimation import uncertainty as U  # noqa: E402

Z = 1.959964


def white(J, e, s, sc):
    return U.covariance(J, s, sc).stderr


def _ar1(u):
    a, b = u[1:], u[:-1]
    den = np.sum(b * b, axis=0)
    rho = np.clip(np.where(den > 0, np.sum(a * b, axis=0) / np.where(den > 0, den, 1.0), 0.0), -0.97, 0.97)
    return rho, np.mean((a - rho * b) ** 2, axis=0)


def andrews(u):
    rho, s2 = _ar1(u)
    num = np.sum(4 * rho**2 * s2**2 / ((1 - rho) ** 6 * (1 + rho) ** 2))
    den = np.sum(s2**2 / (1 - rho) ** 4)
    return float(min(1.1447 * ((num / den if den > 0 else 0.0) * u.shape[0]) ** (1 / 3), u.shape[0] - 1))


def meat(u, lags):
    S = u.T @ u
    for lag in range(1, int(np.floor(lags)) + 1):
        g = u[lag:].T @ u[:-lag]
        S += (1.0 - lag / (lags + 1.0)) * (g + g.T)
    return S


def nw(J, e, s, sc, prewhiten=False):
    Js = J * sc[None, :]
    Ainv = np.linalg.pinv(Js.T @ Js)
    u = Js * e[:, None]
    if prewhiten:
        X, Y = u[:-1], u[1:]
        A = np.linalg.lstsq(X, Y, rcond=None)[0].T
        top = np.max(np.abs(np.linalg.eigvals(A)))
        A = A * 0.97 / top if top > 0.97 else A
        v = Y - X @ A.T
        B = np.linalg.inv(np.eye(len(A)) - A)
        S = B @ meat(v, andrews(v)) @ B.T
    else:
        S = meat(u, andrews(u))
    sd = np.sqrt(np.clip(np.diag(Ainv @ S @ Ainv * np.outer(sc, sc)), 0, None))
    return np.maximum(sd, white(J, e, s, sc))


def ar(J, e, s, sc, crit="bic"):
    if crit == "bic":
        return U.correlated_covariance(J, e, s, sc).stderr
    n = e.size  # AIC: the same model, penalty 2 per coefficient
    from scipy.linalg import solve_toeplitz

    top = int(min(U.MAX_AR_ORDER, n // 10))
    g = np.array([np.dot(e[:n - k], e[k:]) / n for k in range(top + 1)])
    best = (np.log(g[0]), 0, np.zeros(0))
    for p in range(1, top + 1):
        phi = solve_toeplitz(g[:p], g[1:p + 1])
        s2 = g[0] - phi @ g[1:p + 1]
        if not s2 > 0:
            break
        if np.log(s2) + 2 * p / n < best[0]:
            best = (np.log(s2) + 2 * p / n, p, phi)
    _, p, phi = best
    gam = np.zeros(n)
    gam[:p + 1] = g[:p + 1]
    for k in range(p + 1, n):
        gam[k] = phi @ gam[k - p:k][::-1]
    Js = J * sc[None, :]
    Ainv = np.linalg.pinv(Js.T @ Js)
    sd = np.sqrt(np.clip(np.diag(Ainv @ U.toeplitz_quadratic(Js, gam) @ Ainv * np.outer(sc, sc)), 0, None))
    return np.maximum(sd, white(J, e, s, sc))


METHODS = {"white": white, "nw_andrews": nw, "nw_prewhite": lambda *a: nw(*a, prewhiten=True),
           "ar_bic": ar, "ar_aic": lambda *a: ar(*a, crit="aic")}


def main() -> int:
    rows = pickle.loads(Path(sys.argv[1]).read_bytes())
    groups: dict = {}
    for r in rows:
        if "error" not in r and r.get("jre") is not None:
            groups.setdefault(f"{r['condition']}/{r['kind']}", []).append(r)
    out = {}
    for key, rs in sorted(groups.items()):
        names = rs[0]["names"][:-1]
        X = np.array([r["x"] for r in rs])[:, :-1]
        mean, spread = X.mean(0), 2 * Z * X.std(0, ddof=1)
        out[key] = {"fits": len(rs)}
        base = None
        print(key, len(rs), "fits: coverage of the mean / width over spread / width over white")
        for m, f in METHODS.items():
            SD = np.array([f(*r["jre"]) for r in rs])[:, :-1]
            cov = np.mean(np.abs(X - mean) <= Z * SD, axis=0)
            w = 2 * Z * SD.mean(0) / spread
            base = SD.mean(0) if base is None else base
            out[key][m] = {n: {"coverage_of_mean": float(c), "width_over_spread": float(ww),
                               "width_over_white": float(sd / b)}
                           for n, c, ww, sd, b in zip(names, cov, w, SD.mean(0), base)}
            print(f"  {m:<12}", " ".join(f"{n} {c:.2f}/{ww:.2f}/{sd / b:.2f}"
                                          for n, c, ww, sd, b in zip(names, cov, w, SD.mean(0), base)))
    (ROOT / "bench" / "results" / "interval_methods.json").write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
