"""Fitting one operation (paper Section 3): CMA-ES stages with range re-adaptation, a local
least-squares polish, and the Jacobian uncertainty.

Opening: stage 1 fits AO, BO (and the onset delay τ) on the pre-buffer part (θ <= α0); stage 2
fits DO, EO on the whole valid interval with the rest fixed; a joint polish refines all.
Closing: AC, BC, CC (and τ) with DC fixed to the breaker's latest opening AO.
"""

from __future__ import annotations

import time
from functools import partial
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
from .polish import batched_jacobian, polish
from .model_bias import ResidualShape, bias_summary, repeating_rows, updated, varying_part
from .uncertainty import Z95, correlated_covariance
from .warm_start import Prior, sigma0, warm_space
from .window import FitError, FitWindow, block_samples, decimate, prepare_window

_TAU_SCAN = 21  # onset-delay candidates scored when the prior has none
WARM_STALL = 2  # iterations without gain at the noise floor that end a warm CMA-ES run

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
        Samples averaged into one fitting-grid point (anti-alias boxcar), stated at 128 kS/s;
        other rates keep the block's duration (``window.block_samples``).
    block_close_search, search_step_close : int, float
        Coarser grid and RK4 step [s] the closing's CMA-ES search uses before the exact polish.
    tau_max : float
        Largest onset delay between latch shock and motion [s]. After a coil command (no
        vibration channel) the window's own range applies (``FitWindow.tau_range``).
    sigma0 : float
        Initial CMA-ES step size in the unit cube.
    max_readaptations : int
        Range re-adaptation rounds per stage before giving up (paper steps 5–6).
    polish : bool
        Run the local least-squares polish after CMA-ES.
    rules : cmaes.StoppingRules
    noise_floor_blocks : float
        CMA-ES stops early once the block means' residual sum of squares is within this many
        times its expectation at the true parameters (one noise variance per block): the warm
        search's early stop.
    search_floor_blocks : float
        The same, looser, for the cold search's opening stage 1 and closing search, which a
        least-squares step then finishes (opening stage 2 keeps ``noise_floor_blocks``).
    fallback_factor : float
        A warm start whose polished RMSE stays above this factor of the noise floor (or of the
        prior's own ratio) is discarded for the full cold search.
    random_start : bool
        Cold search starts at a random point of the ranges (the paper's protocol) instead of
        their centre.
    take_zero : bool
        Take the transducer's zero (the mean before the latch shock) off before the fit. The gap
        diagnosis fits without it: its own model of the sensor carries the zero.
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
    noise_floor_blocks: float = 2.0
    search_floor_blocks: float = 20.0
    fallback_factor: float = 1.5
    random_start: bool = False
    take_zero: bool = True


def fit_capture(capture: Capture, breaker: Breaker, operation: str, *, dc: float | None = None,
                seed: int = 1, settings: FitSettings = FitSettings(),
                evaluator: Evaluator = evaluate_locally, prior: Prior | None = None,
                index: int = 0) -> FitResult:
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
    prior : Prior, optional
        Warm start (previous fit or design values, see ``warm_start``). Without one, the cold
        search over the breaker file's ranges (the paper's protocol).
    index : int
        In a record of several operations without a vibration channel (an analyser's CO or
        O–CO test), which operation of this kind to fit (0 = the first). The result's
        ``window_s`` is in the whole record's time.

    Raises
    ------
    FitError
        The capture cannot be fitted (the message says why).
    """
    if operation not in ("open", "close"):
        raise FitError(f"operation must be 'open' or 'close', got {operation!r}")
    t0 = time.perf_counter()
    if operation == "close" and breaker.cam is None:
        raise FitError(f"breaker '{breaker.name}' has no cam table: the closing model needs the "
                       "camshaft-to-output-shaft cam profile, which a travel record cannot give; "
                       "only the opening can be fitted (give the design's [cam] profile to fit closings)")
    from .record import operation_capture

    capture, offset_s, picked = operation_capture(capture, breaker, operation, index)
    window = prepare_window(capture, breaker, operation, take_zero=settings.take_zero)
    if operation == "close":
        if dc is None:
            dc, dc_source = breaker.design_parameters()["DC"], "breaker file"
        else:
            dc_source = "opening fit"
        if not np.isfinite(dc) or dc <= 0:
            raise FitError(f"DC must be a positive number of s^-2, got {dc}")
        dc = float(dc)
    shape = prior.residual_shape if prior is not None and prior.operation == operation else None
    if prior is not None and (prior.operation != operation or not prior.usable()):
        prior = None
    fit_one = partial(_fit_opening, shape=shape) if operation == "open" else partial(_fit_closing, dc=dc, shape=shape)
    result, fallback = None, None
    if prior is not None:
        result = fit_one(window, breaker, seed, settings, evaluator, prior=prior)
        result.rmse_rad = _rmse_at_samples(capture, breaker, result, window, dc)
        ratio = result.rmse_rad / window.noise_rad
        limit = max(settings.fallback_factor, 1.2 * (prior.rmse_ratio or 0.0))
        if ratio > limit:
            # A poor prior must not decide the answer: search the whole ranges instead.
            fallback = {"warm_start": prior.source, "rmse_over_noise": float(ratio),
                        "evaluations": result.evaluations}
            result = None
    if result is None:
        result = fit_one(window, breaker, seed, settings, evaluator)
        result.rmse_rad = _rmse_at_samples(capture, breaker, result, window, dc)
        if fallback is not None:
            result.evaluations += fallback["evaluations"]
            result.stages.insert(0, {"fallback": fallback})
            result.start = f"cold search (warm start from {prior.source} left " \
                           f"{fallback['rmse_over_noise']:.1f}× the noise floor)"
    if breaker.estimate_structure and operation == "open":
        from .structure import fit_structure

        breaker = fit_structure(result, window, breaker, settings)  # the curve's own α0 (CO), in the CIs
        result.rmse_rad = _rmse_at_samples(capture, breaker, result, window, dc)
    if operation == "close":
        result.dc_used, result.dc_source = dc, dc_source
    result.fitness = 1.0 / result.rmse_rad if result.rmse_rad > 0 else float("inf")
    if result.interval_noise is not None and result.interval_noise["basis"] == "residual in motion":
        # the residual band: the residual's own rms at the samples where it is wider than the idle noise
        result.interval_noise["band_rad"] = float(max(window.noise_rad, result.rmse_rad))
    result.characteristics = travel_characteristics(
        capture.t, capture.travel, operation, stroke=breaker.stroke, t_start=window.t_start,
        alpha0=result.structure.get("alpha0", {}).get("value", breaker.alpha0))
    from ..vibration import VibrationError, unread as unread_vibration, vibration_characteristics

    try:  # the vibration's latch time and events (service.vibration); a bad channel never fails the fit
        result.characteristics.update(vibration_characteristics(
            capture, operation, window.t_start + result.onset_delay_s, window.t_end,
            model_travel=partial(result.travel_at, breaker=breaker),
            alpha0=result.structure.get("alpha0", {}).get("value", breaker.alpha0)))
    except VibrationError as exc:
        result.characteristics.update(unread_vibration(str(exc)))
    except (ValueError, ArithmeticError):  # a library met a value it cannot use: the travel fit stands
        result.characteristics.update(unread_vibration(
            f"{capture.source or 'the capture'}: the vibration or coil channels hold values the read cannot use "
            "(not finite, or out of any range a sensor gives): the latch time and coil currents are not read"))
    if capture.meta.get("travel_map"):
        from .structure import characteristics_in_record_unit

        result.characteristics_record = characteristics_in_record_unit(capture, operation, window, result, breaker)
    result.command_source = window.command_source
    if picked is not None:
        result.picked = picked
    if offset_s:
        result.window_s = (result.window_s[0] + offset_s, result.window_s[1] + offset_s)
    if window.tau_range is not None and window.shock_found:
        result.warnings.append(f"no vibration channel: the window starts at the {window.command_source} "
                               f"rise and the onset delay was searched in {window.tau_range[0] * 1e3:.1f}–"
                               f"{window.tau_range[1] * 1e3:.1f} ms (coil-to-motion)")
    if not window.shock_found and capture.vibration is not None:
        where = ("the first sample" if window.tau_range is None else
                 f"{window.tau_range[1] * 1e3 - 1:.0f} ms before the travel departs")
        result.warnings.append("no latch-release shock found in the vibration channel: "
                               f"the window starts at {where}")
    if result.rmse_rad > 3.0 * window.noise_rad:
        result.warnings.append(f"the fit leaves {result.rmse_rad / window.noise_rad:.1f}× the noise "
                               "floor: the reduced model does not explain this curve (run hvcb diagnose)")
    if not result.identifiable:
        result.warnings.append("ill-conditioned fit: some parameters are not separately identifiable")
    result.runtime_s = time.perf_counter() - t0
    return result


def _search(score, space: ParameterSpace, seed: int, settings: FitSettings, evaluator, fixed=("tau",),
            target: float | None = None):
    """CMA-ES with range re-adaptation until every estimate is interior (paper steps 5–6)."""
    evaluations, readapt, stages = 0, 0, []
    x0 = None
    if settings.random_start:
        x0 = np.random.default_rng(seed).uniform(0.0, 1.0, len(space.names))
    while True:
        res = cmaes.minimize(lambda U: evaluator(lambda X: score(space.to_physical(X)), U),
                             len(space.names), seed=seed + readapt, sigma0=settings.sigma0,
                             rules=settings.rules, x0=x0 if readapt == 0 else None, target=target,
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


def _fit_opening(window: FitWindow, breaker: Breaker, seed, settings, evaluator,
                 prior: Prior | None = None, *, shape: ResidualShape | None = None) -> FitResult:
    grid = decimate(window.t, window.y, block_samples(settings.block_open, window.sample_rate))
    tau_lo, tau_hi = window.tau_range or (0.0, settings.tau_max)
    above = np.nonzero(grid.y > breaker.alpha0)[0]
    if above.size == 0:
        raise FitError("the opening never reaches the buffer engagement angle α0 "
                       f"({breaker.alpha0:.3f} rad): check the breaker file or the travel scaling")
    n1 = int(above[0])
    if n1 < 8:
        raise FitError("too few samples before buffer engagement to fit the opening spring")
    full = OpeningCurves(breaker, grid)
    ss_full = _within_ss(grid, window)
    target = _floor_target(grid, window, settings.noise_floor_blocks)
    names = list(OPENING_PARAMETERS) + ["tau"]
    scale = np.array([3000.0, 5000.0, 30.0, 5000.0, 1e-3])
    lower = np.array([1.0, 1.0, 0.0, 0.0, tau_lo])
    upper = np.array([1e6, 1e6, 1e4, 1e6, tau_hi])

    def residual_rows(X):
        return grid.weight[None, :] * (full.full(X) - grid.y[None, :])

    if prior is not None:
        x, evaluations, stages, ranges, polished = _warm_search(
            lambda X: weighted_rmse(full.full(X), grid, ss_full), residual_rows,
            (lower, upper, scale), prior, tuple(names), seed, settings, evaluator, target, tau_hi)
        return _finish("open", names, x, residual_rows, scale, lower, upper, window, settings,
                       evaluations, 0, stages, [], ranges, start=f"warm start from {prior.source}",
                       polished=polished, grid=grid, shape=shape)

    ranges = dict(breaker.ranges, tau=(tau_lo, tau_hi))
    pre = OpeningCurves(breaker, _subgrid(grid, n1))
    space1 = ParameterSpace.from_ranges(("AO", "BO", "tau"), ranges)
    ss_pre = _within_ss(pre.grid, window)
    x1, space1, ev1, ra1, st1, hit1 = _search(
        lambda X: weighted_rmse(pre.pre_buffer(X), pre.grid, ss_pre), space1, seed, settings,
        evaluator, target=_floor_target(pre.grid, window, settings.search_floor_blocks))
    if settings.polish and not hit1:
        # CMA-ES stopped in the basin; the least-squares step finds its bottom, so stage 2 fits
        # DO, EO against the right AO, BO (as a fully converged stage 1 would give).
        k = [0, 1, 4]
        pre_rows = lambda X: pre.grid.weight[None, :] * (pre.pre_buffer(X) - pre.grid.y[None, :])  # noqa: E731
        pol = polish(pre_rows, x1, lower[k], upper[k], scale[k], max_nfev=30)
        ev1 += pol.evaluations
        if pol.success and np.sum(pre_rows(pol.x[None, :]) ** 2) <= np.sum(pre_rows(x1[None, :]) ** 2):
            x1 = pol.x
    AO, BO, tau = x1

    def score2(X):
        full_X = np.column_stack([np.full(len(X), AO), np.full(len(X), BO), X, np.full(len(X), tau)])
        return weighted_rmse(full.full(full_X), grid, ss_full)

    space2 = ParameterSpace.from_ranges(("DO", "EO"), ranges)
    # Stage 2 keeps the tight target: it decides whether EO's range must move (steps 5–6).
    x2, space2, ev2, ra2, st2, hit2 = _search(score2, space2, seed + 1000, settings, evaluator,
                                              fixed=(), target=target)
    x = np.array([AO, BO, x2[0], x2[1], tau])
    return _finish("open", names, x, residual_rows, scale, lower, upper, window, settings,
                   ev1 + ev2, ra1 + ra2, st1 + st2, hit1 + hit2,
                   {**space1.as_dict(), **space2.as_dict()}, grid=grid, shape=shape)


def _fit_closing(window: FitWindow, breaker: Breaker, seed, settings, evaluator,
                 prior: Prior | None = None, *, dc: float, shape: ResidualShape | None = None) -> FitResult:
    fs = window.sample_rate
    grid = decimate(window.t, window.y, block_samples(settings.block_close, fs))
    tau_lo, tau_hi = window.tau_range or (0.0, settings.tau_max)
    # Two fidelities: CMA-ES searches with coarse RK4 steps; the polish and the uncertainty use
    # the accurate step, so the reported estimate carries no step-size bias.
    search = ClosingCurves(breaker, decimate(window.t, window.y, block_samples(settings.block_close_search, fs)), dc,
                           dt_max=settings.search_step_close)
    exact = ClosingCurves(breaker, grid, dc)
    ss = _within_ss(search.grid, window)
    target = _floor_target(search.grid, window, settings.noise_floor_blocks)
    names = list(CLOSING_PARAMETERS) + ["tau"]
    scale = np.array([20000.0, 2.0, 10000.0, 1e-3])
    lower = np.array([1.0, 1e-3, 0.0, tau_lo])
    upper = np.array([1e7, 100.0, 1e6, tau_hi])

    def residual_rows(X):
        return grid.weight[None, :] * (exact.full(X) - grid.y[None, :])

    def score(X):
        return weighted_rmse(search.full(X), search.grid, ss)

    if prior is not None:
        x, evaluations, stages, ranges, polished = _warm_search(
            score, residual_rows, (lower, upper, scale), prior, tuple(names), seed, settings,
            evaluator, target, tau_hi)
        return _finish("close", names, x, residual_rows, scale, lower, upper, window, settings,
                       evaluations, 0, stages, [], ranges, start=f"warm start from {prior.source}",
                       polished=polished, grid=grid, shape=shape)
    ranges = dict(breaker.ranges, tau=(tau_lo, tau_hi))
    space = ParameterSpace.from_ranges(("AC", "BC", "CC", "tau"), ranges)
    x, space, ev, ra, st, hit = _search(
        score, space, seed, settings, evaluator,
        target=_floor_target(search.grid, window, settings.search_floor_blocks))
    return _finish("close", names, x, residual_rows, scale, lower, upper, window, settings,
                   ev, ra, st, hit, space.as_dict(), grid=grid, shape=shape)


def _warm_search(score, residual_rows, bounds, prior: Prior, names: tuple, seed, settings,
                 evaluator, target, tau_max: float):
    """The warm path: a least-squares step from the prior, then CMA-ES around it.

    The landscape is narrow (1 % off in the springs is already about 3× the noise floor), so a
    prior is first pulled into its basin by the polish. CMA-ES then searches the box around
    the prior with a σ0 matched to the prior's spread, starting from the best point so far; it
    ends at the noise floor within ``WARM_STALL`` iterations when that point is already there.
    Returns (x, evaluations, stages, ranges, polished) with ``polished`` True when x is the
    polish's own answer.
    """
    lower, upper, scale = bounds
    space, u0 = warm_space(prior, names, tau_max)
    evaluations = 0

    def score_unit(U):
        return evaluator(lambda X: score(space.to_physical(X)), U)

    if prior.onset_delay_s is None:
        # Design values say nothing about the onset delay: scan it at the prior in one call.
        U = np.repeat(u0[None, :], _TAU_SCAN, axis=0)
        U[:, -1] = np.linspace(0.0, 1.0, _TAU_SCAN)
        u0[-1] = U[int(np.nanargmin(score_unit(U))), -1]
        evaluations += _TAU_SCAN
    pol = polish(residual_rows, space.to_physical(u0), lower, upper, scale, max_nfev=30)
    evaluations += pol.evaluations
    u_lm = space.to_unit(pol.x)
    start, polished = u0, False
    if pol.success and np.all((u_lm >= 0) & (u_lm <= 1)):
        f_lm = float(score_unit(u_lm[None, :])[0])
        evaluations += 1
        if f_lm <= target:
            start, polished = u_lm, True
    if polished:
        # The least-squares step already reached the noise floor: nothing CMA-ES could find around
        # it would fit better than noise allows, so it is not run (the warm fit's main cost).
        stage = {"ranges": space.as_dict(), "iterations": 0, "evaluations": 0, "stop": "noise_floor", "reached_by": "least-squares polish",
                 "rmse_grid_rad": f_lm, "warm_start": prior.source, "prior_in_basin": True}
        return pol.x, evaluations, [stage], space.as_dict(), True
    res = cmaes.minimize(score_unit, len(names), seed=seed, x0=start, sigma0=sigma0(prior),
                         rules=settings.rules, target=target, target_window=WARM_STALL,
                         score_start=True)
    evaluations += res.evaluations
    polished = polished and np.array_equal(res.x_best, np.clip(start, 0.0, 1.0))
    stage = {"ranges": space.as_dict(), "iterations": res.iterations,
             "evaluations": res.evaluations, "stop": res.stop_reason,
             "rmse_grid_rad": float(res.f_best), "warm_start": prior.source,
             "prior_in_basin": bool(start is not u0)}
    x = pol.x if polished else space.to_physical(res.x_best)
    return x, evaluations, [stage], space.as_dict(), polished


def _finish(operation, names, x, residual_rows, scale, lower, upper, window, settings,
            evaluations, readaptations, stages, edge_hits, ranges, start="cold search",
            polished=False, *, grid, shape: ResidualShape | None = None) -> FitResult:
    warnings = []
    if edge_hits:
        warnings.append(f"estimates still on a search-range edge after {readaptations} "
                        f"re-adaptations: {', '.join(sorted(set(edge_hits)))}")

    def sse(p):
        r = residual_rows(p[None, :])[0]
        return float(np.sum(r * r))

    if settings.polish and not polished:
        pol = polish(residual_rows, x, lower, upper, scale)
        evaluations += pol.evaluations
        if pol.success and sse(pol.x) <= sse(x):
            x = pol.x
    # The covariance needs the Jacobian at the reported estimate itself.
    # ...and the residual it leaves, with its correlation (AR(p) residual sandwich, uncertainty.py).
    resid, jac = batched_jacobian(residual_rows, x, scale, lower, upper)
    # The interval stands for what varies between operations: the residual less the shape the
    # breaker's recent operations repeat (service.estimation.model_bias), which is its bias.
    t_rel = grid.t - x[-1]
    weight = grid.weight
    varying, smooth = varying_part(resid, weight, t_rel)
    unc = correlated_covariance(jac, varying, window.noise_rad, scale, n_model=len(names) - 1)
    repeat, basis = repeating_rows(shape, smooth, weight, t_rel)
    model_bias = bias_summary(repeat, basis, weight, jac[:, :-1], window.noise_rad, names[:-1])
    new_shape = updated(shape, operation, t_rel, resid / weight)
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
        readaptations=readaptations, stages=stages, warnings=warnings, start=start,
        zero_rad=window.zero_rad, interval_noise=_interval_noise(unc, model_names, window.noise_rad),
        model_bias=model_bias, residual_shape=new_shape)


def _interval_noise(unc, model_names, idle_rad: float) -> dict | None:
    """Which noise the intervals and the residual band stand for (FitResult.interval_noise)."""
    kept = {"repeating_part": "left out: the residual's smooth part is the model's bias (model_bias)"}
    if unc.noise is None:
        return {"basis": "idle samples", "band_rad": float(idle_rad), "idle_noise_rad": float(idle_rad), **kept}
    n = dict(unc.noise)
    widen = dict(zip(model_names, n.pop("widening")))
    return {**n, "band_rad": float(idle_rad), "widening": widen, **kept}  # band_rad: fit_capture, at the samples


def _floor_target(grid, window: FitWindow, blocks: float) -> float:
    """The grid RMSE [rad] that counts as "at the noise floor" for the early stop.

    At the true parameters each block mean misses the model by noise alone, so the blocks add
    about one noise variance each to the within-block scatter; the target allows
    ``blocks`` of them.
    """
    n = float(np.sum(grid.count))
    excess = blocks * grid.y.size * window.noise_rad**2
    return float(np.sqrt((_within_ss(grid, window) + excess) / n))


def _within_ss(grid, window: FitWindow) -> float:
    """Expected within-block residual sum of squares [rad²]: the noise the block means average out."""
    return float(np.sum(grid.count - 1.0)) * window.noise_rad**2


def _subgrid(grid, n):
    from .window import Grid

    return Grid(grid.t[:n], grid.y[:n], grid.count[:n], grid.spread[:n])


def _rmse_at_samples(capture, breaker, result: FitResult, window: FitWindow, dc=None) -> float:
    """The reported RMSE: model against every measured sample of the valid interval."""
    x = [result.parameters[k] for k in result.parameter_names[:-1]] + [result.onset_delay_s]
    if result.operation == "open":
        theta = OpeningCurves.at(window.t, x, breaker)
    else:
        theta = ClosingCurves.at(window.t, x, breaker, dc)
    return float(np.sqrt(np.mean((theta - window.y) ** 2)))
