"""Fitting one operation (paper Section 3): CMA-ES stages with range re-adaptation, a local
least-squares polish, and the Jacobian uncertainty.

Opening: stage 1 fits AO, BO (and the onset delay τ) on the pre-buffer part (θ <= α0); stage 2
fits DO, EO on the whole valid interval with the rest fixed; a joint polish refines all.
Closing: AC, BC, CC (and τ) with DC fixed to the breaker's latest opening AO.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from drivers.capture import Capture
from ..mechanics.breaker import CLOSING_PARAMETERS, OPENING_PARAMETERS, Breaker
from ..mechanics.characteristics import travel_characteristics
from . import cmaes
from .curves import ClosingCurves, OpeningCurves, weighted_rmse
from .parameter_space import ParameterSpace
from .result import FitResult
from .uncertainty import Z95, covariance, polish
from .window import FitError, FitWindow, decimate, prepare_window

Evaluator = Callable[[Callable, np.ndarray], np.ndarray]


def evaluate_locally(curve_rmse: Callable, X: np.ndarray) -> np.ndarray:
    """Default evaluator: the whole population in one vectorised call."""
    return curve_rmse(X)


@dataclass(frozen=True)
class FitSettings:
    """Knobs of the estimator (defaults are the product's).

    Attributes
    ----------
    block_open, block_close : int
        Samples averaged into one fitting-grid point (anti-alias boxcar).
    block_close_search, search_step_close : int, float
        Coarser grid and RK4 step [s] the closing's CMA-ES search uses before the exact polish.
    tau_max : float
        Largest onset delay between latch shock and motion [s].
    sigma0 : float
        Initial CMA-ES step size in the unit cube.
    max_readaptations : int
        Range re-adaptation rounds per stage before giving up (paper steps 5–6).
    polish : bool
        Run the local least-squares polish after CMA-ES.
    rules : cmaes.StoppingRules
    """

    block_open: int = 32
    block_close: int = 8
    block_close_search: int = 32
    search_step_close: float = 1 / 4000
    tau_max: float = 2e-3
    sigma0: float = 0.3
    max_readaptations: int = 8
    polish: bool = True
    rules: cmaes.StoppingRules = field(default_factory=cmaes.StoppingRules)


def fit_capture(capture: Capture, breaker: Breaker, operation: str, *, dc: float | None = None,
                seed: int = 1, settings: FitSettings = FitSettings(),
                evaluator: Evaluator = evaluate_locally) -> FitResult:
    """Estimate the model parameters of one operation.

    Parameters
    ----------
    capture : Capture
        The recording (travel [rad from closed], optional vibration [g]).
    breaker : Breaker
    operation : {"open", "close"}
    dc : float, optional
        For closings, DC = AO [s^-2] from the breaker's latest opening fit; the breaker file's
        design value when omitted.
    seed : int
        Explicit CMA-ES seed.
    evaluator : callable
        ``evaluator(score, X) -> f``; inject a pool here. The default scores the population
        in one vectorised call.

    Raises
    ------
    FitError
        The capture cannot be fitted (the message says why).
    """
    if operation not in ("open", "close"):
        raise FitError(f"operation must be 'open' or 'close', got {operation!r}")
    t0 = time.perf_counter()
    window = prepare_window(capture, breaker, operation)
    if operation == "open":
        result = _fit_opening(window, breaker, seed, settings, evaluator)
    else:
        if dc is None:
            dc, dc_source = breaker.design_parameters()["DC"], "breaker file"
        else:
            dc_source = "opening fit"
        if not np.isfinite(dc) or dc <= 0:
            raise FitError(f"DC must be a positive number of s^-2, got {dc}")
        result = _fit_closing(window, breaker, float(dc), seed, settings, evaluator)
        result.dc_used, result.dc_source = float(dc), dc_source
    result.rmse_rad = _rmse_at_samples(capture, breaker, result, window)
    result.fitness = 1.0 / result.rmse_rad if result.rmse_rad > 0 else float("inf")
    result.characteristics = travel_characteristics(
        capture.t, capture.travel, operation, stroke=breaker.stroke, t_start=window.t_start,
        alpha0=breaker.alpha0)
    if not window.shock_found and capture.vibration is not None:
        result.warnings.append("no latch-release shock found in the vibration channel: "
                               "the window starts at the first sample")
    if result.rmse_rad > 3.0 * window.noise_rad:
        result.warnings.append(f"the fit leaves {result.rmse_rad / window.noise_rad:.1f}× the noise "
                               "floor: the reduced model does not explain this curve (run hvcb diagnose)")
    if not result.identifiable:
        result.warnings.append("ill-conditioned fit: some parameters are not separately identifiable")
    result.runtime_s = time.perf_counter() - t0
    return result


def _search(score, space: ParameterSpace, seed: int, settings: FitSettings, evaluator, fixed=("tau",)):
    """CMA-ES with range re-adaptation until every estimate is interior (paper steps 5–6)."""
    evaluations, readapt, stages = 0, 0, []
    while True:
        res = cmaes.minimize(lambda U: evaluator(lambda X: score(space.to_physical(X)), U),
                             len(space.names), seed=seed + readapt, sigma0=settings.sigma0,
                             rules=settings.rules,
                             edge_dims=tuple(i for i, n in enumerate(space.names) if n not in fixed))
        evaluations += res.evaluations
        x = space.to_physical(res.x_best)
        stages.append({"ranges": space.as_dict(), "iterations": res.iterations,
                       "evaluations": res.evaluations, "stop": res.stop_reason,
                       "rmse_grid_rad": float(res.f_best)})
        hit = space.edges_hit(x, fixed=fixed)
        if res.stop_reason == "edge" and not hit:
            # The distribution sits on the edge even if its best sample does not.
            x = space.to_physical(res.x_mean)
            hit = space.edges_hit(x, fixed=fixed)
        if not hit or readapt >= settings.max_readaptations:
            return x, space, evaluations, readapt, stages, hit
        space = space.readapted(x, fixed=fixed)
        readapt += 1


def _fit_opening(window: FitWindow, breaker: Breaker, seed, settings, evaluator) -> FitResult:
    grid = decimate(window.t, window.y, settings.block_open)
    above = np.nonzero(grid.y > breaker.alpha0)[0]
    if above.size == 0:
        raise FitError("the opening never reaches the buffer engagement angle α0 "
                       f"({breaker.alpha0:.3f} rad): check the breaker file or the travel scaling")
    n1 = int(above[0])
    if n1 < 8:
        raise FitError("too few samples before buffer engagement to fit the opening spring")
    ranges = dict(breaker.ranges, tau=(0.0, settings.tau_max))
    pre = OpeningCurves(breaker, _subgrid(grid, n1))
    full = OpeningCurves(breaker, grid)

    space1 = ParameterSpace.from_ranges(("AO", "BO", "tau"), ranges)
    ss_pre, ss_full = _within_ss(pre.grid, window), _within_ss(grid, window)
    x1, space1, ev1, ra1, st1, hit1 = _search(
        lambda X: weighted_rmse(pre.pre_buffer(X), pre.grid, ss_pre), space1, seed, settings, evaluator)
    AO, BO, tau = x1

    def score2(X):
        full_X = np.column_stack([np.full(len(X), AO), np.full(len(X), BO), X, np.full(len(X), tau)])
        return weighted_rmse(full.full(full_X), grid, ss_full)

    space2 = ParameterSpace.from_ranges(("DO", "EO"), ranges)
    x2, space2, ev2, ra2, st2, hit2 = _search(score2, space2, seed + 1000, settings, evaluator, fixed=())
    x = np.array([AO, BO, x2[0], x2[1], tau])
    names = list(OPENING_PARAMETERS) + ["tau"]
    scale = np.array([3000.0, 5000.0, 30.0, 5000.0, 1e-3])
    lower = np.array([1.0, 1.0, 0.0, 0.0, 0.0])
    upper = np.array([1e6, 1e6, 1e4, 1e6, settings.tau_max])

    def residuals(p):
        return grid.weight * (full.full(p[None, :])[0] - grid.y)

    return _finish("open", names, x, residuals, scale, lower, upper, window, settings,
                   ev1 + ev2, ra1 + ra2, st1 + st2, hit1 + hit2,
                   {**space1.as_dict(), **space2.as_dict()})


def _fit_closing(window: FitWindow, breaker: Breaker, dc, seed, settings, evaluator) -> FitResult:
    grid = decimate(window.t, window.y, settings.block_close)
    # Two fidelities: CMA-ES searches with coarse RK4 steps; the polish and the uncertainty use
    # the accurate step, so the reported estimate carries no step-size bias.
    search = ClosingCurves(breaker, decimate(window.t, window.y, settings.block_close_search), dc,
                           dt_max=settings.search_step_close)
    exact = ClosingCurves(breaker, grid, dc)
    ranges = dict(breaker.ranges, tau=(0.0, settings.tau_max))
    space = ParameterSpace.from_ranges(("AC", "BC", "CC", "tau"), ranges)
    ss = _within_ss(search.grid, window)
    x, space, ev, ra, st, hit = _search(lambda X: weighted_rmse(search.full(X), search.grid, ss),
                                        space, seed, settings, evaluator)
    names = list(CLOSING_PARAMETERS) + ["tau"]
    scale = np.array([20000.0, 2.0, 10000.0, 1e-3])
    lower = np.array([1.0, 1e-3, 0.0, 0.0])
    upper = np.array([1e7, 100.0, 1e6, settings.tau_max])

    def residuals(p):
        return grid.weight * (exact.full(p[None, :])[0] - grid.y)

    return _finish("close", names, x, residuals, scale, lower, upper, window, settings,
                   ev, ra, st, hit, space.as_dict())


def _finish(operation, names, x, residuals, scale, lower, upper, window, settings,
            evaluations, readaptations, stages, edge_hits, ranges) -> FitResult:
    warnings = []
    if edge_hits:
        warnings.append(f"estimates still on a search-range edge after {readaptations} "
                        f"re-adaptations: {', '.join(sorted(set(edge_hits)))}")
    if settings.polish:
        pol = polish(residuals, x, lower, upper, scale)
        evaluations += pol.evaluations
        if pol.success and np.sum(residuals(pol.x) ** 2) <= np.sum(residuals(x) ** 2):
            x = pol.x
        jac = pol.jacobian
    else:
        jac = _jacobian(residuals, x, scale)
    unc = covariance(jac, window.noise_rad, scale, n_model=len(names) - 1)
    if x[-1] <= lower[-1] + 1e-9 or x[-1] >= upper[-1] - 1e-9:
        warnings.append(f"the onset delay sits on its bound ({x[-1] * 1e3:.2f} ms): the start of "
                        "motion does not match the model, and the confidence intervals understate "
                        "the uncertainty (run hvcb diagnose)")
    model_names = names[:-1]
    params = {n: float(v) for n, v in zip(model_names, x[:-1])}
    stderr = {n: float(s) for n, s in zip(model_names, unc.stderr[:-1])}
    ci95 = {n: (params[n] - Z95 * stderr[n], params[n] + Z95 * stderr[n]) for n in model_names}
    return FitResult(
        operation=operation, parameters=params, stderr=stderr, ci95=ci95,
        correlation=unc.correlation.tolist(), parameter_names=names, rmse_rad=float("nan"),
        fitness=float("nan"), window_s=(window.t_start, window.t_end), onset_delay_s=float(x[-1]),
        noise_rad=window.noise_rad, evaluations=int(evaluations), runtime_s=0.0,
        identifiable=unc.identifiable, condition_number=unc.condition_number, ranges=ranges,
        readaptations=readaptations, stages=stages, warnings=warnings)


def _jacobian(residuals, x, scale):
    r0 = residuals(x)
    J = np.empty((r0.size, x.size))
    for i in range(x.size):
        h = 1e-6 * scale[i]
        xp = x.copy()
        xp[i] += h
        J[:, i] = (residuals(xp) - r0) / h
    return J


def _within_ss(grid, window: FitWindow) -> float:
    """Expected within-block residual sum of squares [rad²]: the noise the block means average out."""
    return float(np.sum(grid.count - 1.0)) * window.noise_rad**2


def _subgrid(grid, n):
    from .window import Grid

    return Grid(grid.t[:n], grid.y[:n], grid.count[:n], grid.spread[:n])


def _rmse_at_samples(capture, breaker, result: FitResult, window: FitWindow) -> float:
    """The reported RMSE: model against every measured sample of the valid interval."""
    x = [result.parameters[k] for k in result.parameter_names[:-1]] + [result.onset_delay_s]
    if result.operation == "open":
        theta = OpeningCurves.at(window.t, x, breaker)
    else:
        theta = ClosingCurves.at(window.t, x, breaker, result.dc_used)
    return float(np.sqrt(np.mean((theta - window.y) ** 2)))
