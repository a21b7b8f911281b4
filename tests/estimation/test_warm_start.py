"""Warm starts: same answer as the cold search, fewer evaluations, and a poor prior falls back."""

import numpy as np
import pytest

from service.acquisition.capture_file import read_capture
from service.estimation import cmaes, fit_capture
from service.estimation.warm_start import Prior, prior_from_design, prior_from_fit


@pytest.fixture(scope="module")
def captures(samples_dir):
    return {op: read_capture(samples_dir / f"{op}-nominal.cfg") for op in ("open", "close")}


@pytest.fixture(scope="module")
def cold(captures, breaker):
    return {op: fit_capture(cap, breaker, op, seed=1) for op, cap in captures.items()}


def _same_fit(a, b):
    """Two fits agree well inside their own uncertainty (a tenth of a standard error)."""
    for name, value in a.parameters.items():
        assert abs(value - b.parameters[name]) <= 0.1 * b.stderr[name], \
            f"{name}: {value} vs {b.parameters[name]} (se {b.stderr[name]})"
    assert a.rmse_rad == pytest.approx(b.rmse_rad, rel=1e-3)


def _scaled(prior: Prior, factor: float) -> Prior:
    return Prior(prior.operation, {k: v * factor for k, v in prior.parameters.items()},
                 prior.onset_delay_s, prior.spread, prior.rmse_ratio, f"×{factor} prior")


@pytest.mark.parametrize("op", ["open", "close"])
def test_warm_start_from_design_values_matches_the_cold_fit_with_fewer_evaluations(
        captures, breaker, cold, op):
    warm = fit_capture(captures[op], breaker, op, seed=1, prior=prior_from_design(breaker, op))
    _same_fit(warm, cold[op])
    assert warm.start == "warm start from breaker file design values"
    assert warm.evaluations < cold[op].evaluations / 3


@pytest.mark.parametrize("op", ["open", "close"])
def test_previous_fit_round_trips_as_a_prior(captures, breaker, cold, op):
    prior = prior_from_fit(cold[op].to_dict(), "previous fit")
    assert prior is not None and prior.onset_delay_s == pytest.approx(cold[op].onset_delay_s)
    assert prior.rmse_ratio == pytest.approx(cold[op].rmse_rad / cold[op].noise_rad)
    warm = fit_capture(captures[op], breaker, op, seed=2, prior=prior)
    _same_fit(warm, cold[op])
    assert warm.stages[0]["stop"] == "noise_floor"


@pytest.mark.parametrize("op", ["open", "close"])
def test_prior_forty_percent_off_converges_to_the_cold_fit(captures, breaker, cold, op):
    prior = _scaled(prior_from_fit(cold[op].to_dict(), "previous fit"), 1.4)
    warm = fit_capture(captures[op], breaker, op, seed=1, prior=prior)
    _same_fit(warm, cold[op])


def test_a_prior_far_off_falls_back_to_the_cold_search(captures, breaker, cold):
    prior = _scaled(prior_from_design(breaker, "close"), 0.01)
    result = fit_capture(captures["close"], breaker, "close", seed=1, prior=prior)
    assert result.start.startswith("cold search (warm start from ×0.01 prior left")
    assert result.stages[0]["fallback"]["rmse_over_noise"] > 1.5
    _same_fit(result, cold["close"])


@pytest.mark.parametrize("op", ["open", "close"])
def test_any_prior_ends_at_the_cold_fit(captures, breaker, cold, op):
    # Whether the polish recovers a prior 100× off or the fallback takes over, accuracy never
    # depends on the prior.
    prior = _scaled(prior_from_design(breaker, op), 100.0)
    _same_fit(fit_capture(captures[op], breaker, op, seed=1, prior=prior), cold[op])


def test_unusable_prior_is_ignored(captures, breaker, cold):
    assert prior_from_fit({"operation": "open", "parameters": {"AO": 1.0}}, "x") is None
    closing_prior = prior_from_design(breaker, "close")
    result = fit_capture(captures["open"], breaker, "open", seed=1, prior=closing_prior)
    assert result.start == "cold search"


def test_noise_floor_stop_ends_the_search_once_the_target_is_held():
    def f(X):
        return 1.0 + np.sum((X - 0.4) ** 2, axis=1)
    plain = cmaes.minimize(f, 3, seed=3)
    early = cmaes.minimize(f, 3, seed=3, target=1.001)
    assert early.stop_reason == "noise_floor"
    assert early.f_best <= 1.001
    assert early.iterations < plain.iterations
