"""CMA-ES in ask/tell form with the paper's stopping rules (Section 3.3).

The caller injects ``evaluate``: it scores a whole population at once, so the population can be
vectorised, compiled or sent to a pool. The search runs in the unit cube; candidates outside it
are scored at their projection plus a quadratic penalty.
"""

from __future__ import annotations

import random
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

with warnings.catch_warnings():
    # cma's package tries matplotlib for its own cma.plot() and warns when it is absent (the core
    # install has none). hvcb never plots through cma (service/plots.py, the plots extra), so the
    # warning is third-party noise on every command; only this import's warning is silenced.
    warnings.filterwarnings("ignore", message="Could not import matplotlib", category=UserWarning)
    from cma import purecma


@dataclass(frozen=True)
class StoppingRules:
    """The paper's four stopping rules (any one ends the search)."""

    tol_x: float = 1e-8          # change of the normalised mean between iterations
    tol_fun: float = 1e-8        # change of the best fitness ...
    tol_fun_window: int = 20     # ... over this many iterations
    tol_sigma: float = 1e-8      # step size
    max_iterations: int = 1000


@dataclass
class CMAResult:
    """Outcome of one CMA-ES run in the unit cube."""

    x_best: np.ndarray
    f_best: float
    x_mean: np.ndarray
    evaluations: int
    iterations: int
    stop_reason: str
    history: list = field(default_factory=list)  # (iteration, best f, sigma)


def minimize(evaluate: Callable[[np.ndarray], np.ndarray], dimension: int, *, seed: int,
             x0=None, sigma0: float = 0.3, popsize: int | None = None,
             rules: StoppingRules = StoppingRules(), record: bool = False,
             edge_dims: tuple = (), edge: float = 0.01, edge_sigma: float = 0.05,
             target: float | None = None, target_window: int = 3,
             target_rtol: float = 2e-3, score_start: bool = False) -> CMAResult:
    """Minimise ``evaluate`` over the unit cube [0, 1]^dimension.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(X) -> f`` with X of shape (λ, dimension) in the unit cube; returns λ values
        (NaN or inf for failed candidates, which are resampled-as-worst).
    seed : int
        Explicit seed (pycma's ``seed=0`` would mean "time"; here every seed is literal).
    edge_dims : tuple of int
        Dimensions whose range may be re-adapted: once the mean is pinned within ``edge`` of a
        bound with a step size below ``edge_sigma``, the run stops (``edge``) so the caller can
        move the range instead of converging against the bound.
    target : float, optional
        Early stop (``noise_floor``): once the best value is at or below ``target`` and has
        improved by less than ``target_rtol`` (relative) over ``target_window`` iterations. At
        the noise floor CMA-ES only shuffles noise; the local polish finishes faster.
    score_start : bool
        Score ``x0`` first and keep it as the best so far (a warm start that is already at
        the noise floor then ends the search within ``target_window`` iterations).
    """
    if seed is None:
        raise ValueError("an explicit seed is required")
    rng = random.Random(int(seed))
    x0 = [0.5] * dimension if x0 is None else [float(v) for v in x0]
    es = purecma.CMAES(x0, sigma0, popsize=popsize, randn=rng.normalvariate,
                       maxfevals=10**9)
    best_x = np.array(x0)
    best_f = np.inf
    best_hist: list[float] = []
    history = []
    prev_mean = np.array(es.xmean, dtype=float)
    reason = "max_iterations"
    it = 0
    evaluations = 0
    if score_start:
        start = np.clip(best_x, 0.0, 1.0)
        f0 = float(np.asarray(evaluate(start[None, :]), dtype=float)[0])
        evaluations += 1
        if np.isfinite(f0):
            best_x, best_f = start, f0
        best_hist.append(best_f)
    while it < rules.max_iterations:
        it += 1
        arx = es.ask()  # plain floats: purecma's arithmetic is slow on numpy scalars
        X = np.array(arx, dtype=float)
        inside = np.clip(X, 0.0, 1.0)
        f = np.asarray(evaluate(inside), dtype=float)
        evaluations += len(X)
        finite = np.isfinite(f)
        if not finite.all():
            worst = np.max(f[finite]) if finite.any() else 1e6
            f = np.where(finite, f, 10.0 * abs(worst) + 1.0)
        penalised = f + np.sum((X - inside) ** 2, axis=1)
        es.tell(arx, penalised.tolist())
        k = int(np.argmin(penalised))
        if f[k] < best_f and np.all(X[k] == inside[k]):
            best_f, best_x = float(f[k]), inside[k].copy()
        best_hist.append(best_f)
        if record:
            history.append((it, best_f, float(es.sigma)))
        mean = np.array(es.xmean, dtype=float)
        if np.max(np.abs(mean - prev_mean)) < rules.tol_x:
            reason = "tol_x"
            break
        prev_mean = mean
        w = rules.tol_fun_window
        if len(best_hist) > w and best_hist[-w - 1] - best_hist[-1] < rules.tol_fun:
            reason = "tol_fun"
            break
        # At the noise floor but on a re-adaptable edge: let the edge rule move the range.
        on_edge = any(best_x[d] < edge or best_x[d] > 1 - edge for d in edge_dims)
        if (target is not None and best_f <= target and len(best_hist) > target_window
                and best_hist[-target_window - 1] - best_f <= target_rtol * best_f
                and not on_edge):
            reason = "noise_floor"
            break
        if es.sigma < rules.tol_sigma:
            reason = "tol_sigma"
            break
        if edge_dims and es.sigma < edge_sigma and any(
                mean[d] < edge or mean[d] > 1 - edge for d in edge_dims):
            reason = "edge"
            break
    if not np.isfinite(best_f):
        # Every candidate hit the boundary: fall back to the final mean.
        best_x = np.clip(np.array(es.xmean, dtype=float), 0, 1)
        best_f = float(evaluate(best_x[None, :])[0])
        evaluations += 1
    return CMAResult(best_x, best_f, np.clip(np.array(es.xmean, dtype=float), 0, 1), evaluations,
                     it, reason, history)
