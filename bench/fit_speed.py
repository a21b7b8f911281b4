"""Fit speed on the reference captures, against a naive baseline.

Times the product's opening and closing fits as the median over 20 fits each, on one core, in
two ways: cold (the paper's protocol: CMA-ES from a random start within Table 2's ranges) and
warm (the service's path: a prior from the breaker's previous good fit). In the same run it
times a naive baseline: the same CMA-ES stages and settings, but every candidate simulated
with ``solve_ivp`` on the full 128 kHz curve. Times are CPU time of this process, because
the machine may be shared; wall-clock is recorded next to them. Writes
bench/results/fit_speed.json.

    python bench/fit_speed.py [--fits 20] [--naive-runs 1] [--naive-budget-s 600]

A naive run that exceeds its CPU-time budget is stopped; its time is then a lower bound (and so is
the ratio), which the JSON marks with ``*_naive_lower_bound``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import time
from pathlib import Path

# One core means one BLAS thread too: OpenBLAS's second thread on a busy 2-core machine waits for
# the other core and multiplies a fit's small matrix products' time (measured: the closing's
# settled-rest check took 20-40 ms instead of 0.02). Set before numpy loads.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from service.acquisition.capture_file import read_capture  # noqa: E402
from service.breaker_file import load_breaker  # noqa: E402
from service.estimation import fit_capture  # noqa: E402
from service.estimation.fit import FitSettings, _search  # noqa: E402
from service.estimation.parameter_space import ParameterSpace  # noqa: E402
from service.estimation.warm_start import prior_from_fit  # noqa: E402
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
    state = {"evals": 0, "t0": time.process_time()}

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
        if time.process_time() - state["t0"] > budget_s:
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
    state = {"evals": 0, "t0": time.process_time()}

    def score(X):
        res = []
        for AC, BC, CC, tau in X:
            state["evals"] += 1
            if time.process_time() - state["t0"] > budget_s:
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


def _time_fits(cap, breaker, op, n, **kw):
    """CPU time [s] (this process, one core) and wall time [s] of ``n`` fits with seeds 1..n."""
    cpu, wall, evals, results = [], [], [], []
    for seed in range(1, n + 1):
        c0, w0 = time.process_time(), time.perf_counter()
        r = fit_capture(cap, breaker, op, seed=seed, **kw)
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
        evals.append(r.evaluations)
        results.append(r)
    return cpu, wall, evals, results


def _warm_prior(breaker, op, cap_sibling, cap_same):
    """The service's prior: the breaker's previous good fit.

    Opening: the cold fit of the sibling recording (same breaker, other noise). Closing (one
    recording only): the cold fit of the same recording with every parameter moved by a seeded
    2 % (about the change between two operations), so the prior is not the answer itself.
    """
    if op == "open":
        prev = fit_capture(cap_sibling, breaker, op, seed=99)
        return prior_from_fit(prev.to_dict(), "fit of open-nominal-ascii")
    prev = fit_capture(cap_same, breaker, op, seed=99).to_dict()
    rng = np.random.default_rng(7)
    prev["parameters"] = {k: v * (1 + 0.02 * rng.standard_normal()) for k, v in prev["parameters"].items()}
    return prior_from_fit(prev, "fit of close-nominal moved by 2 %")


def _warm_parts(cap, breaker, op, prior, n) -> dict:
    """Where a warm fit's time goes [ms CPU, medians]: the window, the travel characteristics and
    the vibration read (both run in every fit_capture), and the estimator proper (the rest)."""
    from service.mechanics.characteristics import travel_characteristics
    from service.vibration import vibration_characteristics

    def median_ms(f):
        out = []
        for _ in range(n):
            t = time.process_time()
            f()
            out.append(time.process_time() - t)
        return 1e3 * statistics.median(out)

    r = fit_capture(cap, breaker, op, prior=prior)
    w = prepare_window(cap, breaker, op)
    t_motion = w.t_start + r.onset_delay_s
    parts = {"fit_capture": median_ms(lambda: fit_capture(cap, breaker, op, prior=prior)),
             "window": median_ms(lambda: prepare_window(cap, breaker, op)),
             "travel_characteristics": median_ms(lambda: travel_characteristics(
                 cap.t, cap.travel, op, stroke=breaker.stroke, t_start=w.t_start, alpha0=breaker.alpha0)),
             "vibration_read": median_ms(lambda: vibration_characteristics(
                 cap, op, t_motion, w.t_end, model_travel=lambda t: r.travel_at(t, breaker),
                 alpha0=breaker.alpha0))}
    parts["estimator"] = parts["fit_capture"] - parts["window"] - parts["travel_characteristics"] - parts["vibration_read"]
    return {k: round(v, 3) for k, v in parts.items()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fits", type=int, default=20)
    ap.add_argument("--naive-budget-s", type=float, default=300.0)
    ap.add_argument("--samples", default=str(REPO.parent / "shared" / "samples"))
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "fit_speed.json"))
    args = ap.parse_args()
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    except (AttributeError, OSError):
        pass
    breaker = load_breaker(REPO / "config" / "breakers" / "reference-252kV.toml")
    samples = Path(args.samples)
    caps = {"open": read_capture(samples / "open-nominal.cfg"),
            "close": read_capture(samples / "close-nominal.cfg")}
    sibling = read_capture(samples / "open-nominal-ascii.cfg")
    # The paper's protocol for the cold figure: a random start within Table 2's ranges.
    cold_settings = FitSettings(random_start=True)
    results = {"clock": "CPU time of this process (one core); *_wall_* keys are wall-clock",
               "uptime_before": subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(),
               "load_average_at_start": list(os.getloadavg())}
    for op, cap in caps.items():
        fit_capture(cap, breaker, op)  # compile and warm caches
        prior = _warm_prior(breaker, op, sibling, cap)
        for mode, kw in (("cold", {"settings": cold_settings}), ("warm", {"prior": prior})):
            cpu, wall, evals, res = _time_fits(cap, breaker, op, args.fits, **kw)
            key = f"{op}_{mode}"
            results[f"{key}_median_s"] = statistics.median(cpu)
            results[f"{key}_p90_s"] = float(np.percentile(cpu, 90))
            results[f"{key}_wall_median_s"] = statistics.median(wall)
            results[f"{key}_wall_p90_s"] = float(np.percentile(wall, 90))
            results[f"{key}_median_evaluations"] = statistics.median(evals)
            results[f"{key}_fallbacks"] = sum(r.start.startswith("cold search") for r in res) if mode == "warm" else None
            print(f"{op} {mode}: median {results[f'{key}_median_s'] * 1e3:.1f} ms CPU "
                  f"(p90 {results[f'{key}_p90_s'] * 1e3:.1f} ms; wall median "
                  f"{results[f'{key}_wall_median_s'] * 1e3:.1f} ms) over {args.fits} fits, "
                  f"median {results[f'{key}_median_evaluations']:.0f} evaluations")
        results[f"{op}_warm_prior"] = prior.source
        results[f"{op}_warm_parts_ms"] = _warm_parts(cap, breaker, op, prior, args.fits)
        print(f"{op} warm, its parts [ms CPU]: {results[f'{op}_warm_parts_ms']}")

    settings = FitSettings()
    dc = breaker.design_parameters()["DC"]
    for op, fn in (("open", lambda b: naive_opening_fit(caps["open"], breaker, settings, b)),
                   ("close", lambda b: naive_closing_fit(caps["close"], breaker, settings, b, dc))):
        t0 = time.process_time()
        try:
            fn(args.naive_budget_s)
            naive_s, extrapolated = time.process_time() - t0, False
        except Budget:
            # Stopped at the budget: the time spent is a lower bound of the naive fit's time.
            naive_s, extrapolated = time.process_time() - t0, True
        results[f"{op}_naive_s"] = naive_s
        results[f"{op}_naive_lower_bound"] = extrapolated
        results[f"{op}_naive_ratio"] = naive_s / results[f"{op}_cold_median_s"]
        results[f"{op}_naive_warm_ratio"] = naive_s / results[f"{op}_warm_median_s"]
        print(f"{op} naive (solve_ivp per candidate, 128 kHz): {naive_s:.1f} s CPU"
              f"{' (stopped at budget: a lower bound)' if extrapolated else ''}; "
              f"ratio {results[f'{op}_naive_ratio']:.0f}x cold, "
              f"{results[f'{op}_naive_warm_ratio']:.0f}x warm")
    results["load_average_at_end"] = list(os.getloadavg())
    results["uptime_after"] = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    results["cores"] = 1
    results["blas_threads"] = int(os.environ["OPENBLAS_NUM_THREADS"])
    results["machine"] = os.uname().machine
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
