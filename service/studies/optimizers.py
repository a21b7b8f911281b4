"""Optimizer comparison on one opening curve (paper Table 6, Fig. 10).

One noisy opening capture (SNR 50 dB) of a parameter set drawn in Table 2's ranges; every
method minimises the same objective — the weighted RMSE [rad] on the decimated fitting grid
(``window.decimate``, ``curves.OpeningCurves``) of AO, BO, DO, EO and the onset delay τ, all
normalised to [0, 1] over Table 2's ranges (τ over [0, 2 ms]) — from 30 seeds each, with one
stopping rule: 2,000 iterations, or a best-fitness change below 1e-6 rad over the last 20
iterations (the paper's window; one iteration of a population method is one generation).

Methods (none written here):
- CMA-ES: the project's ask/tell ``service.estimation.cmaes.minimize`` (pycma's purecma).
- PSO: nevergrad ``ConfPSO(transform="arctan", popsize=40)`` (nevergrad's registered PSO).
- GA: nevergrad ``EvolutionStrategy(recombination_ratio=1, popsize=40, offsprings=40,
  ranker="simple")``: a real-coded (μ+λ) genetic algorithm, Gaussian mutation of every
  offspring followed by crossover with a random parent. (nevergrad's ``RecombiningGA`` is a
  (1+1) discrete-mutation scheme, not a population GA; ``GeneticDE``/``TwoPointsDE`` are DE.)
- DE: ``scipy.optimize.differential_evolution`` (best1bin, popsize 15·d, no polish; the stop
  rule is applied through its callback; its own tol/atol disabled).
- NLS: ``scipy.optimize.least_squares`` (trf) from a uniform random start in the unit cube,
  max 2,000 function evaluations, ftol 1e-6 (relative change of ½‖r‖²).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from scipy.optimize import differential_evolution, least_squares

from ..estimation import cmaes
from ..estimation.curves import OpeningCurves, weighted_rmse
from ..estimation.parameter_space import ParameterSpace
from ..estimation.window import decimate, prepare_window
from ..mechanics.breaker import OPENING_PARAMETERS, TABLE2_RANGES
from . import report
from .common import load_reference
from .synthetic_sets import draw_parameter_sets, study_capture

NAME = "optimizers"
SNR_DB = 50.0
MAX_ITERATIONS = 2000
TOL_FUN = 1e-6
TOL_WINDOW = 20
TAU_MAX = 2e-3
BLOCK = 32
PAPER = {"CMA-ES": {"MRE_pct": 2.63, "runtime_s": 0.69, "evaluations": 740, "fitness_sd": 1.05},
         "PSO": {"MRE_pct": 4.92, "runtime_s": 0.75, "evaluations": 2240, "fitness_sd": 1.16},
         "GA": {"MRE_pct": 3.88, "runtime_s": 0.75, "evaluations": 2120, "fitness_sd": 1.11},
         "DE": {"MRE_pct": 2.79, "runtime_s": 0.96, "evaluations": 2160, "fitness_sd": 1.09},
         "NLS": {"MRE_pct": 4.61, "runtime_s": 2.42, "evaluations": 4615, "fitness_sd": 1.13}}


class Objective:
    """RMSE [rad] on the fitting grid as a function of unit-cube points; counts evaluations."""

    def __init__(self, breaker, capture):
        window = prepare_window(capture, breaker, "open")
        self.grid = decimate(window.t, window.y, BLOCK)
        self.curves = OpeningCurves(breaker, self.grid)
        self.space = ParameterSpace.from_ranges(OPENING_PARAMETERS + ("tau",),
                                                dict(TABLE2_RANGES, tau=(0.0, TAU_MAX)))
        self.evaluations = 0
        self.history = []   # (evaluations, best RMSE so far)
        self.best = np.inf

    def __call__(self, U):
        """Scores rows of ``U`` (n, 5) in [0, 1]; returns n RMSE values [rad]."""
        U = np.clip(np.atleast_2d(np.asarray(U, dtype=float)), 0.0, 1.0)
        f = weighted_rmse(self.curves.full(self.space.to_physical(U)), self.grid)
        f = np.where(np.isfinite(f), f, 1e3)
        self.evaluations += len(U)
        self.best = min(self.best, float(np.min(f)))
        self.history.append((self.evaluations, self.best))
        return f

    def residuals(self, u):
        """Residual vector whose norm is the RMSE (for least squares)."""
        x = self.space.to_physical(np.clip(u, 0, 1))[None, :]
        self(u[None, :])
        r = self.grid.weight * (self.curves.full(x)[0] - self.grid.y)
        return r / np.sqrt(np.sum(self.grid.count))


class StallRule:
    """The shared stop rule: best fitness changed by < TOL_FUN over TOL_WINDOW iterations."""

    def __init__(self):
        self.best = []

    def update(self, best: float) -> bool:
        self.best.append(best)
        w = TOL_WINDOW
        return len(self.best) > w and self.best[-w - 1] - self.best[-1] < TOL_FUN


def run_cmaes(obj, seed):
    rules = cmaes.StoppingRules(tol_x=0.0, tol_fun=TOL_FUN, tol_fun_window=TOL_WINDOW,
                                tol_sigma=0.0, max_iterations=MAX_ITERATIONS)
    res = cmaes.minimize(obj, 5, seed=seed, rules=rules)
    return res.x_best, res.iterations


def _run_nevergrad(obj, seed, optimizer_cls, popsize):
    import nevergrad as ng

    param = ng.p.Array(shape=(5,), lower=0.0, upper=1.0)
    param.random_state = np.random.RandomState(seed)
    opt = optimizer_cls(parametrization=param, budget=MAX_ITERATIONS * popsize)
    rule = StallRule()
    best_x, best_f = None, np.inf
    for it in range(1, MAX_ITERATIONS + 1):
        cands = [opt.ask() for _ in range(popsize)]
        f = obj(np.array([c.value for c in cands]))
        for c, v in zip(cands, f):
            opt.tell(c, float(v))
        k = int(np.argmin(f))
        if f[k] < best_f:
            best_f, best_x = float(f[k]), np.array(cands[k].value)
        if rule.update(best_f):
            break
    return best_x, it


def run_pso(obj, seed):
    import nevergrad as ng

    return _run_nevergrad(obj, seed, ng.families.ConfPSO(transform="arctan", popsize=40), 40)


def run_ga(obj, seed):
    import nevergrad as ng

    ga = ng.families.EvolutionStrategy(recombination_ratio=1.0, popsize=40, offsprings=40,
                                       only_offsprings=False, ranker="simple")
    return _run_nevergrad(obj, seed, ga, 40)


def run_de(obj, seed):
    rule = StallRule()
    iterations = [0]

    def callback(intermediate_result):
        iterations[0] += 1
        return rule.update(float(intermediate_result.fun))

    res = differential_evolution(lambda U: obj(np.asarray(U).T), [(0.0, 1.0)] * 5,
                                 maxiter=MAX_ITERATIONS, tol=0.0, atol=0.0, polish=False,
                                 rng=np.random.default_rng(seed), vectorized=True,
                                 updating="deferred", callback=callback)
    return res.x, iterations[0]


def run_nls(obj, seed):
    x0 = np.random.default_rng(seed).uniform(0.0, 1.0, 5)
    res = least_squares(obj.residuals, x0, bounds=(0.0, 1.0), method="trf", ftol=TOL_FUN,
                        xtol=None, gtol=None, max_nfev=MAX_ITERATIONS)
    return res.x, int(res.nfev)


METHODS = {"CMA-ES": run_cmaes, "PSO": run_pso, "GA": run_ga, "DE": run_de, "NLS": run_nls}


def nevergrad_available() -> bool:
    try:
        import nevergrad  # noqa: F401
    except ImportError:
        return False
    return True


def run(out_dir: Path, *, seed: int = 2026, quick: bool = False) -> dict:
    t0 = time.perf_counter()
    breaker = load_reference()
    sets, _ = draw_parameter_sets(breaker, 1, np.random.default_rng([seed, 6]))
    truth = sets[0]
    capture, _, sigma = study_capture(breaker, "open", truth, rng=np.random.default_rng([seed, 7]),
                                      snr_db=SNR_DB)
    true_vec = np.array([truth[n] for n in OPENING_PARAMETERS])
    n_runs = 2 if quick else 30
    methods = {k: v for k, v in METHODS.items() if k not in ("PSO", "GA") or nevergrad_available()}
    results, curves = {}, {}
    for name, method in methods.items():
        runs = []
        for r in range(n_runs):
            obj = Objective(breaker, capture)
            start = time.perf_counter()
            u, iterations = method(obj, seed + r)
            runtime = time.perf_counter() - start
            x = obj.space.to_physical(np.clip(u, 0, 1))
            f = float(obj(np.asarray(u)[None, :])[0])
            rel = np.abs(x[:4] - true_vec) / true_vec
            runs.append({"estimate": dict(zip(OPENING_PARAMETERS + ("tau",), x)), "rmse_grid_rad": f,
                         "mre_pct": float(100 * rel.mean()), "rel_err_pct": dict(zip(OPENING_PARAMETERS, 100 * rel)),
                         "runtime_s": runtime, "evaluations": obj.evaluations - 1,
                         "iterations": iterations})
            if r == 0:
                curves[name] = obj.history
        rm = np.array([x["rmse_grid_rad"] for x in runs])
        results[name] = {
            "MRE_pct": float(np.mean([x["mre_pct"] for x in runs])),
            "MRE_pct_per_parameter": {n: float(np.mean([x["rel_err_pct"][n] for x in runs]))
                                      for n in OPENING_PARAMETERS},
            "runtime_s": float(np.mean([x["runtime_s"] for x in runs])),
            "evaluations": float(np.mean([x["evaluations"] for x in runs])),
            "iterations": float(np.mean([x["iterations"] for x in runs])),
            "fitness_rmse_mean_rad": float(rm.mean()),
            "fitness_rmse_sd_rad": float(rm.std(ddof=1)) if len(rm) > 1 else float("nan"),
            "fitness_F_sd": float((1 / rm).std(ddof=1)) if len(rm) > 1 else float("nan"),
            "runs": runs,
        }
    data = {"study": NAME, "seed": seed, "quick": quick, "runs_per_method": n_runs,
            "snr_db": SNR_DB, "noise_rad": sigma, "truth": truth, "grid_points": int(obj.grid.t.size),
            "stopping_rule": f"{MAX_ITERATIONS} iterations or best-fitness change < {TOL_FUN} rad over "
                             f"{TOL_WINDOW} iterations",
            "methods_missing": sorted(set(METHODS) - set(methods)),
            "results": results, "paper": PAPER, "runtime_s": time.perf_counter() - t0}
    report.write_json(out_dir, NAME, data)
    _write_table(out_dir, data)
    _plot(out_dir, curves)
    return data


def _write_table(out_dir, data):
    rows = []
    for name, res in data["results"].items():
        p = PAPER[name]
        rows.append([name, res["MRE_pct"], p["MRE_pct"], res["runtime_s"], p["runtime_s"],
                     res["evaluations"], p["evaluations"], res["iterations"],
                     res["fitness_rmse_sd_rad"], res["fitness_F_sd"], p["fitness_sd"]])
    cols = ["method", "MRE [%]", "paper MRE [%]", "runtime [s]", "paper runtime [s]", "evaluations",
            "paper evaluations", "iterations", "sd of final RMSE [rad]", "sd of F = 1/RMSE",
            "paper sd of fitness"]
    per = [[name] + [res["MRE_pct_per_parameter"][n] for n in OPENING_PARAMETERS]
           for name, res in data["results"].items()]
    notes = [f"One opening curve at SNR {data['snr_db']:g} dB (σ = {data['noise_rad'] * 1e3:.2f} mrad), "
             f"{data['runs_per_method']} seeds per method, truth drawn in Table 2's ranges: "
             + ", ".join(f"{n} {data['truth'][n]:.4g}" for n in OPENING_PARAMETERS) + ".",
             f"Stopping rule for all: {data['stopping_rule']}. Fitting grid: {data['grid_points']} "
             f"block means of {BLOCK} samples. Runtime is wall time on a shared 2-core machine.",
             "Method choices: see the module docstring of service/studies/optimizers.py."]
    if data["methods_missing"]:
        notes.append(f"Not run (nevergrad not importable): {', '.join(data['methods_missing'])}.")
    report.write_markdown(out_dir, NAME, "Optimizer comparison (paper Table 6)", rows, cols,
                          sections=[("Mean relative error per parameter [%]",
                                     ["method"] + list(OPENING_PARAMETERS), per)], notes=notes)


def _plot(out_dir, curves):
    fig, ax = report.new_figure(figsize=(7, 4))
    for name, hist in curves.items():
        h = np.array(hist)
        ax.semilogy(h[:, 0], h[:, 1], label=name)
    ax.set_xlabel("function evaluations")
    ax.set_ylabel("best RMSE on the fitting grid [rad]")
    ax.set_title("Convergence, first run of each method (paper Fig. 10)")
    ax.legend()
    report.save_figure(fig, Path(out_dir) / f"{NAME}.png")
