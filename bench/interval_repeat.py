"""Is a fit's 95 % interval as wide as the estimates' real spread? Repeated openings of several
prototypes, clean and with mild unmodelled effects through a realistic sensor (issue 51 item 1).

For each prototype (A, B, C: the three that share the groups interface) and each condition:

- ``clean``: one unit with no effect, white noise 1.5 mrad and 16 bits (the prototype's own
  capture);
- ``realistic``: one unit with mild effects (viscous friction, orifice buffer and linkage
  kinematics at 0.3 of the prototype's realistic strength) read through one realistic
  transducer (service/prototypes/sensor.py: zero, gain, bow, torsional modes struck at the latch
  and the impact, the ADC),

``--n`` openings under fixed conditions are fitted in order, as the service would (each fit's
residual shape rides on to the next one's warm start). Each fit's weighted residual rows and
Jacobian are kept, and the interval is computed by each estimator on the same fits:

- ``ar_full``: the AR(p) sandwich of the whole residual in motion (the estimator of rounds 5-6);
- ``idle``: σ²(JᵀJ)⁻¹ with σ from the idle samples (the classical interval);
- ``ar_less_history``: the AR sandwich of the residual less the mean residual of the breaker's
  earlier operations (their ``ResidualShape``, as the service carries it), the first
  ``SHAPE_MIN_OPS`` fits less their own smooth part instead;
- ``ar_less_smooth``: what ships (service/estimation/model_bias.py): the AR sandwich of the
  residual less its projection on Legendre polynomials up to ``SMOOTH_DEGREE`` over the valid
  interval, a single capture's own estimate of the repeat.

For each parameter and estimator: the share of intervals holding the mean estimate (target
0.90-0.99) and the mean half-width over 1.96 sd of the estimates (target ≤ 2, clean ≤ 1.5).
Writes bench/results/interval_repeat.json.

    flock /tmp/hvcb-heavy.lock nice -n 5 .venv/bin/python bench/interval_repeat.py --n 40
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")
BREAKER = ROOT / "config" / "breakers" / "reference-252kV.toml"
MILD_SHARE = 0.3
MILD = ("viscous_friction", "orifice_buffer", "linkage_kinematics")
METHODS = ("ar_full", "idle", "ar_less_history", "ar_less_smooth")


def _mild_effects(p: str) -> dict:
    if p == "a":
        from service.prototypes.a.effects import REALISTIC
        return {k: MILD_SHARE * REALISTIC[k] for k in MILD if k in REALISTIC}
    from service.studies.gap.runner import generator
    ops = getattr(generator(p), "OPERATIONS", None)
    if ops is None:
        ops = __import__(f"service.prototypes.{p}.effects", fromlist=["OPERATIONS"]).OPERATIONS
    return {k: MILD_SHARE for k in MILD if k in ops}


def run_series(p: str, condition: str, n: int, seed: int) -> dict:
    """n openings of one unit, fitted in order with the service's warm start; kept per fit."""
    from service.breaker_file import load_breaker
    from service.estimation import fit as fitmod
    from service.estimation.warm_start import prior_from_design, prior_from_fit
    from service.prototypes import sensor
    from service.studies.gap.runner import generator

    gen = generator(p)
    breaker = load_breaker(BREAKER)
    rng = np.random.default_rng([seed, ord(p), condition == "realistic"])
    unit = gen.make_unit(rng, effects=_mild_effects(p) if condition == "realistic" else {})
    sunit = sensor.draw_unit(rng) if condition == "realistic" else None
    kept, rows = {}, []
    real = fitmod.correlated_covariance

    def keep(jac, resid, noise, scale, n_model=None, variance_factor=1.0):
        kept.update(jac=np.asarray(jac), resid=np.asarray(resid), noise=noise, scale=np.asarray(scale),
                    n_model=n_model)
        return real(jac, resid, noise, scale, n_model, variance_factor)

    fitmod.correlated_covariance = keep
    real_varying, real_repeating = fitmod.varying_part, fitmod.repeating_rows

    def keep_varying(resid, weight, t_rel):
        kept.update(weight=np.asarray(weight), t_rel=np.asarray(t_rel), full=np.asarray(resid))
        return real_varying(resid, weight, t_rel)

    def keep_repeating(shape, smooth, weight, t_rel):
        kept["shape"] = shape
        return real_repeating(shape, smooth, weight, t_rel)

    fitmod.varying_part, fitmod.repeating_rows = keep_varying, keep_repeating
    prior = prior_from_design(breaker, "open")
    try:
        for i in range(n):
            cap, truth = gen.simulate_capture(unit, "open", rng=rng)
            if sunit is not None:
                cap = sensor.apply(cap, sunit, rng, stroke=breaker.stroke, operation="open")
            try:
                res = fitmod.fit_capture(cap, breaker, "open", prior=prior)
            except Exception as exc:  # a failed fit is a row with its reason, counted
                rows.append({"error": str(exc)})
                continue
            prior = prior_from_fit(res.to_dict(), f"fit {i}") or prior
            rows.append({"x": [res.parameters[k] for k in res.parameter_names[:-1]],
                         "names": res.parameter_names[:-1], "rmse_over_noise": res.rmse_rad / res.noise_rad,
                         **{k: kept[k] for k in ("jac", "noise", "scale", "n_model", "weight", "t_rel")},
                         "resid": kept["full"], "shape": kept["shape"]})
    finally:
        fitmod.correlated_covariance = real
        fitmod.varying_part, fitmod.repeating_rows = real_varying, real_repeating
    return {"rows": rows, "unit": p, "condition": condition}


def stderr_by(method: str, r: dict) -> np.ndarray:
    from service.estimation.model_bias import SHAPE_MIN_OPS, varying_part
    from service.estimation.uncertainty import correlated_covariance, covariance

    jac, resid, noise, scale, k = r["jac"], r["resid"], r["noise"], r["scale"], r["n_model"]
    if method == "idle":
        return covariance(jac, noise, scale, k).stderr[:k]
    if method == "ar_full":
        return correlated_covariance(jac, resid, noise, scale, k).stderr[:k]
    if method == "ar_less_history":
        shape = r["shape"]
        if shape is None or shape.count < SHAPE_MIN_OPS:  # the first fits: their smooth part instead
            return stderr_by("ar_less_smooth", r)
        # less a mean of k earlier residuals, which adds 1/k of one operation's variation back
        e = resid - r["weight"] * shape.at(r["t_rel"])
        return correlated_covariance(jac, e, noise, scale, k,
                                     variance_factor=1.0 / (1.0 + 1.0 / shape.count)).stderr[:k]
    if method == "ar_less_smooth":  # what ships (service/estimation/model_bias.py)
        e, _ = varying_part(resid, r["weight"], r["t_rel"])
        return correlated_covariance(jac, e, noise, scale, k).stderr[:k]
    raise ValueError(method)


def judge(series: dict) -> dict:
    rows = [r for r in series["rows"] if "error" not in r]
    out = {"fits": len(rows), "failed": [r["error"] for r in series["rows"] if "error" in r]}
    if len(rows) < 5:
        return out
    names = rows[0]["names"]
    X = np.array([r["x"] for r in rows])
    mean, sd = X.mean(axis=0), X.std(axis=0, ddof=1)
    out["rmse_over_noise_median"] = float(np.median([r["rmse_over_noise"] for r in rows]))
    out["sd_estimate"] = dict(zip(names, sd.tolist()))
    for m in METHODS:
        se = np.array([stderr_by(m, r) for r in rows])
        half = 1.959964 * se
        inside = np.abs(X - mean) <= half
        out[m] = {n: {"coverage_of_mean": float(inside[:, j].mean()),
                      "halfwidth_over_spread": float(half[:, j].mean() / (1.959964 * sd[j]))}
                  for j, n in enumerate(names)}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=40, help="openings per prototype and condition")
    ap.add_argument("--seed", type=int, default=51)
    ap.add_argument("--prototypes", default="a,b,c")
    args = ap.parse_args()
    up0 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    t0 = time.perf_counter()
    result = {"uptime_before": up0, "n_per_series": args.n, "seed": args.seed, "methods": METHODS,
              "mild_effects_share": MILD_SHARE, "series": {}}
    for p in args.prototypes.split(","):
        for cond in ("clean", "realistic"):
            s = run_series(p, cond, args.n, args.seed)
            result["series"][f"{p}/{cond}"] = j = judge(s)
            line = " ".join(f"{m}:" + ",".join(f"{n}={v['coverage_of_mean']:.2f}/{v['halfwidth_over_spread']:.2f}"
                                              for n, v in j[m].items()) for m in METHODS if m in j)
            print(f"{p}/{cond}: {j['fits']} fits, rmse/noise {j.get('rmse_over_noise_median', float('nan')):.2f}  {line}",
                  flush=True)
    result["runtime_s"] = time.perf_counter() - t0
    result["uptime_after"] = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    out = ROOT / "bench" / "results" / "interval_repeat.json"
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
