"""Temperature compensation: the baseline learns each parameter's temperature slope (within the
range physics allows) and the statistic uses the compensated residual."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from histories import DO_NOMINAL, BO_NOMINAL, first_alarm, seasonal_history
from service.alarms import DriftSettings, DriftState, FitObservation, check_temperature, replay

SETTINGS = DriftSettings()
SEEDS = range(10)


@functools.lru_cache(maxsize=None)
def _alarms(give_temperature: bool, parameter="DO", nominal=DO_NOMINAL, rel_per_k=-0.004, **kw):
    out = []
    for seed in SEEDS:
        history = seasonal_history(seed, nominal=nominal, rel_per_k=rel_per_k, n_ops=400,
                                   give_temperature=give_temperature, **kw)
        state, events = replay(history, SETTINGS, parameter=parameter)
        out.append((first_alarm(events, "warning"), state))
    return out


def test_a_season_of_temperature_raises_nothing_when_the_temperature_is_given():
    runs = _alarms(True)
    assert [w for w, _ in runs] == [None] * len(SEEDS)
    rel = []
    for _, state in runs:
        assert state.compensated and state.baseline.compensated
        assert state.baseline.t_span >= SETTINGS.temperature_span_k
        rel.append(state.baseline.slope / DO_NOMINAL)  # simulated: dx/dT = -0.004 * nominal
    # learnt slope: the simulated -0.4 %/K; each breaker within 0.1 %/K, the fleet within 0.015
    assert np.all(np.abs(np.array(rel) + 0.004) < 0.001), rel
    assert np.mean(rel) == pytest.approx(-0.004, abs=1.5e-4)


def test_without_the_temperature_the_season_raises_false_alarms_and_says_so():
    runs = _alarms(False)
    assert sum(w is not None for w, _ in runs) >= len(SEEDS) // 2
    assert all(not state.compensated for _, state in runs)


def test_bo_temperature_slope_is_learnt_too():
    runs = _alarms(True, parameter="BO", nominal=BO_NOMINAL, rel_per_k=-0.0003)
    assert [w for w, _ in runs] == [None] * len(SEEDS)
    lo, hi = SETTINGS.slope_range("BO")
    for _, state in runs:
        assert lo <= state.baseline.slope / state.baseline.mean <= hi


def test_a_leak_in_a_compensated_breaker_is_still_alarmed():
    for seed in range(4):
        history = seasonal_history(seed, nominal=DO_NOMINAL, rel_per_k=-0.004, n_ops=400,
                                   slope=-0.01, drift_from=300)
        _, events = replay(history, SETTINGS, parameter="DO")
        op = first_alarm(events)
        assert op is not None and 300 < op <= 310, (seed, op)


def test_the_slope_stays_in_the_range_physics_allows():
    """A DO that rose with temperature would be unphysical: the slope is clipped at 0."""
    runs = _alarms(True, rel_per_k=+0.002)
    for _, state in runs:
        assert state.baseline.slope == pytest.approx(0.0, abs=1e-12)


def test_a_fit_without_temperature_in_a_compensated_baseline_gets_a_wider_band():
    state = _alarms(True)[0][1]
    _, with_t = state.model.predict(state.model.t_mean, 0.0)
    _, without = state.model.predict(None, 0.0)
    assert without > 2 * with_t


@pytest.mark.parametrize("value, message", [
    (500.0, "outside -60..100 C"), (float("nan"), "must be finite"), ("warm", "must be a number")])
def test_an_implausible_temperature_is_refused_in_words(value, message):
    with pytest.raises(ValueError, match=message):
        check_temperature(value)
    with pytest.raises(ValueError, match=message):
        FitObservation(operation_id=1, time=seasonal_history(0, nominal=1.0, rel_per_k=0, n_ops=1)[0].time,
                       value=1.0, temperature=value)


def test_state_with_temperature_round_trips():
    import json
    state = _alarms(True)[1][1]
    assert DriftState.from_dict(json.loads(json.dumps(state.to_dict(), allow_nan=False))) == state


def test_the_theil_sen_slope_is_scipys():
    from scipy import stats

    from service.alarms.baseline import theil_sen_slope

    rng = np.random.default_rng(1)
    t = rng.uniform(-25, 40, 60)
    x = 39.5 * (1 - 0.004 * (t - 20)) + rng.normal(0, 0.6, 60)
    x[[3, 17]] *= 0.7  # outliers: the median of pairwise slopes shrugs them off
    assert theil_sen_slope(x, t) == pytest.approx(stats.theilslopes(x, t)[0], rel=1e-12)
    assert theil_sen_slope(x, np.full(60, 5.0)) is None
