"""Fit speed on the reference captures, against a naive baseline.

Times the product's opening fit (both stages, polish included) and closing fit as the median
over at least 20 fits each, on one core. In the same run it times a naive baseline: the same
CMA-ES stages and settings, but every candidate simulated with ``solve_ivp`` on the full
128 kHz curve. Prints both and their ratio; writes bench/results/fit_speed.json.

    python bench/fit_speed.py [--fits 20] [--naive-runs 1] [--naive-budget-s 600]

A naive run that exceeds its time budget is stopped; its time is then a lower bound (and so is
the ratio), which the JSON marks with ``*_naive_lower_bound``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from service.acquisition.capture_file import read_capture  # noqa: E402
from service.breaker_file import load_breaker  # noqa: E402
from service.estimation import fit_capture  # noqa: E402
from service.estimation.fit import FitSettings, _search  # noqa: E402
from service.estimation.parameter_space import ParameterSpace  # noqa: E402
from service.estimation.window import prepare_window  # noqa: E402
from service.mechanics.closing import closing_rhs  # noqa: E402
from service.mechanics.opening import opening_rhs  # noqa: E402


class Budget(Exception):
    pass


def naive_opening_fit(capture, breaker, settings, budget_s):
    """Paper pipeline with solve_ivp per candidate at every measured sample."""
    win = prepare_window(capture, breaker, "open")
    t, y = win.t, win.y
    stage1 = y <= breaker.alpha0
    n1 = int(np.argmax(~stage1)) if (~stage1).any() else y.size
    ranges = dict(breaker.ranges, tau=(0.0, settings.tau_max))
    state = {"evals": 0, "t0": time.perf_counter()}

    def simulate(p, tau, tt):
        def rhs(_, x):
            return opening_rhs(_, x, p, breaker.CO, breaker.alpha0)
        tm = tt - tau
        out = np.zeros_like(tt)
        m = tm > 0
        if m.any():
            sol = solve_ivp(rhs, (0, tm[-1]), [0.0, 0.0], t_eval=tm[m], rtol=1e-8, atol=1e-10,
                            max_step=1e-4)
            out[m] = sol.y[0] if sol.success else np.nan
        return out

    def count():
        state["evals"] += 1
        if time.perf_counter() - state["t0"] > budget_s:
            raise Budget

    def score1(X):
        res = []
        for AO, BO, tau in X:
            count()
            m = simulate({"AO": AO, "BO": BO, "DO": 0.0, "EO": 0.0}, tau, t[:n1])
            res.append(np.sqrt(np.mean((m - y[:n1]) ** 2)))
        return np.array(res)

    x1, *_ = _search(score1, ParameterSpace.from_ranges(("AO", "BO", "tau"), ranges), 1, settings,
                     lambda s, X: s(X))

    def score2(X):
        res = []
        for DO, EO in X:
            count()
            m = simulate({"AO": x1[0], "BO": x1[1], "DO": DO, "EO": EO}, x1[2], t)
            res.append(np.sqrt(np.mean((m - y) ** 2)))
        return np.array(res)

    _search(score2, ParameterSpace.from_ranges(("DO", "EO"), ranges), 1001, settings, lambda s, X: s(X), fixed=())
    return state["evals"]


def naive_closing_fit(capture, breaker, settings, budget_s, dc):
    win = prepare_window(capture, breaker, "close")
    t, y = win.t, win.y
    g = breaker.closing_geometry
    ranges = dict(breaker.ranges, tau=(0.0, settings.tau_max))
    state = {"evals": 0, "t0": time.perf_counter()}

    def score(X):
        res = []
        for AC, BC, CC, tau in X:
            state["evals"] += 1
            if time.perf_counter() - state["t0"] > budget_s:
                raise Budget
            p = {"AC": AC, "BC": BC, "CC": CC, "DC": dc}
            tm = t - tau
            m = tm > 0
            out = np.full_like(t, breaker.cam.theta2[0])
            sol = solve_ivp(lambda _, x: closing_rhs(_, x, p, breaker.cam, g), (0, tm[-1]),
                            [g.theta1_start, 0.0], t_eval=tm[m], rtol=1e-8, atol=1e-10)
            if sol.success and sol.y.shape[1] == m.sum():
                out[m] = breaker.cam.evaluate(sol.y[0])[0]
            else:
                out[:] = np.nan
            res.append(np.sqrt(np.mean((out - y) ** 2)))
        return np.array(res)

    _search(score, ParameterSpace.from_ranges(("AC", "BC", "CC", "tau"), ranges), 1, settings, lambda s, X: s(X))
    return state["evals"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fits", type=int, default=20)
    ap.add_argument("--naive-budget-s", type=float, default=300.0)
    ap.add_argument("--samples", default=str(REPO.parent / "shared" / "samples"))
    args = ap.parse_args()
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    except (AttributeError, OSError):
        pass
    breaker = load_breaker(REPO / "config" / "breakers" / "reference-252kV.toml")
    samples = Path(args.samples)
    cap_open = read_capture(samples / "open-nominal.cfg")
    cap_close = read_capture(samples / "close-nominal.cfg")
    settings = FitSettings()
    results = {}
    for op, cap in (("open", cap_open), ("close", cap_close)):
        fit_capture(cap, breaker, op)  # compile and warm caches
        times, evals = [], []
        for seed in range(1, args.fits + 1):
            r = fit_capture(cap, breaker, op, seed=seed)
            times.append(r.runtime_s)
            evals.append(r.evaluations)
        results[f"{op}_median_s"] = statistics.median(times)
        results[f"{op}_p90_s"] = float(np.percentile(times, 90))
        results[f"{op}_median_evaluations"] = statistics.median(evals)
        print(f"{op}: median {results[f'{op}_median_s'] * 1e3:.1f} ms over {args.fits} fits "
              f"(p90 {results[f'{op}_p90_s'] * 1e3:.1f} ms, median {results[f'{op}_median_evaluations']:.0f} evaluations)")

    dc = breaker.design_parameters()["DC"]
    for op, fn in (("open", lambda b: naive_opening_fit(cap_open, breaker, settings, b)),
                   ("close", lambda b: naive_closing_fit(cap_close, breaker, settings, b, dc))):
        t0 = time.perf_counter()
        try:
            evals = fn(args.naive_budget_s)
            naive_s, extrapolated = time.perf_counter() - t0, False
        except Budget:
            # Stopped at the budget: the time spent is a lower bound of the naive fit's time.
            naive_s, extrapolated = time.perf_counter() - t0, True
        results[f"{op}_naive_s"] = naive_s
        results[f"{op}_naive_lower_bound"] = extrapolated
        results[f"{op}_naive_ratio"] = naive_s / results[f"{op}_median_s"]
        print(f"{op} naive (solve_ivp per candidate, 128 kHz): {naive_s:.1f} s"
              f"{' (stopped at budget: a lower bound)' if extrapolated else ''}; "
              f"ratio {results[f'{op}_naive_ratio']:.0f}x")
    results["cores"] = 1
    results["machine"] = os.uname().machine
    out = REPO / "bench" / "results" / "fit_speed.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {out}")

if __name__ == "__main__":
    main()
