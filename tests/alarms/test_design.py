"""The detector's design: thresholds derived from target run lengths, self-starting scores,
a baseline that learns while quiet and then freezes, settings loaded from text."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from histories import BO_NOMINAL, DO_NOMINAL, fit_history
from service.alarms import DriftSettings, DriftState, replay, update
from service.alarms.design import cusum_arl

SETTINGS = DriftSettings()


def test_thresholds_follow_from_the_design_false_alarm_rates():
    s = SETTINGS
    assert s.sides == 4  # DO falling, BO both ways, the latch time rising
    arl_w = cusum_arl(0.0, k=s.k, h=s.h_warning, z_cap=s.z_cap)
    arl_a = cusum_arl(0.0, k=s.k, h=s.h_alarm, z_cap=s.z_cap)
    # 1 %: the Markov chain's ARL steps slightly with h where the capped increment's point mass
    # crosses a state boundary, so the root is found to about that.
    assert arl_w == pytest.approx(s.sides * 1e4 / s.design_false_warnings_per_10k, rel=0.01)
    assert arl_a == pytest.approx(s.sides * 1e4 / s.design_false_alarms_per_10k, rel=0.01)
    # fewer watched sides -> each may be noisier for the same per-breaker rate
    do_only = DriftSettings(watched={"DO": "falling"})
    assert do_only.h_warning < s.h_warning and do_only.h_alarm < s.h_alarm


def test_self_starting_scores_of_an_in_control_breaker_are_standard_normal():
    """Hawkins (1987): against a baseline that learns every in-control fit, the predictive-t
    scores are independent N(0, 1). The window learns only while quiet, which must keep that."""
    settings = DriftSettings(baseline_max=400)
    scores = []
    for seed in range(5):
        state = DriftState.new("BO", settings)
        for o in fit_history(seed + 500, nominal=BO_NOMINAL, n_ops=420):
            state, _ = update(state, o, settings)
            if state.last_score is not None and o.operation_id > settings.baseline_n:
                scores.append(state.last_score)
    u = np.array(scores)
    assert u.size == 5 * 400
    assert abs(u.mean()) < 4 / np.sqrt(u.size)
    assert abs(u.std() - 1.0) < 0.05
    assert stats.kstest(u, "norm").pvalue > 1e-3


def test_the_window_learns_while_quiet_and_freezes_at_baseline_max():
    settings = DriftSettings(baseline_max=60)
    state, _ = replay(fit_history(3, nominal=DO_NOMINAL, n_ops=200), settings, parameter="DO")
    assert state.frozen and state.baseline.n == 60 and state.baseline.frozen
    assert 20 <= state.fits_monitored and state.baseline.operation_ids[-1] < 200


def test_fits_of_a_drift_do_not_enter_the_baseline():
    history = fit_history(4, nominal=DO_NOMINAL, slope=-0.01, n_ops=60)
    state, events = replay(history, SETTINGS, parameter="DO")
    alarm_op = next(e.operation_id for e in events if e.level == "alarm")
    run = next(e for e in events if e.level == "alarm").evidence["operation_ids"]
    # Only the excursion's first fit can enter: whether a fit is learned is decided before its
    # value is seen (that keeps the baseline unbiased in control).
    assert set(state.baseline.operation_ids) & set(run) <= {run[0]}
    assert max(state.baseline.operation_ids) <= run[0] < alarm_op


def test_settings_from_toml_text_and_errors_in_words():
    s = DriftSettings.from_toml('[alarms]\nbaseline_n = 12\n[alarms.watched]\nDO = "falling"\n')
    assert s.baseline_n == 12 and dict(s.watched) == {"DO": "falling"}
    with pytest.raises(ValueError, match="config.toml is not valid TOML"):
        DriftSettings.from_toml("[alarms\n", source="config.toml")
    with pytest.raises(ValueError, match=r"config.toml: k: Input should be greater than 0 \(got -1\)"):
        DriftSettings.from_toml("k = -1", source="config.toml")
    with pytest.raises(ValueError, match="must be a table"):
        DriftSettings.from_mapping(["k"])


def test_a_version_1_state_keeps_its_frozen_baseline_and_its_alarm():
    v1 = {"version": 1, "parameter": "DO", "phase": "monitoring", "collected": [],
          "baseline": {"mean": 41.0, "sd": 0.6, "n": 20, "operation_ids": [1, 3],
                       "excluded_operation_ids": []},
          "s_rising": 0.0, "s_falling": 9.5, "run_rising": [], "run_falling": [5, 7],
          "run_length_rising": 0, "run_length_falling": 2, "level": "alarm", "acknowledged": False,
          "acknowledged_by": None, "acknowledged_at": None, "below_count": 0, "episode": 1,
          "last_operation_id": 7, "last_time": "2026-03-02T14:00:00Z", "last_z": -4.0,
          "last_score": -4.0, "held": None, "outliers_ignored": 0, "fits_monitored": 2}
    state = DriftState.from_dict(v1)
    assert state.frozen and state.level == "alarm" and state.episode == 1
    assert state.baseline.mean == 41.0 and state.baseline.operation_ids == (1, 3)
    from service.alarms import FitObservation
    from datetime import datetime, timezone
    after, _ = update(state, FitObservation(operation_id=8, time=datetime(2026, 3, 3, tzinfo=timezone.utc),
                                            value=41.0), SETTINGS)
    assert after.baseline.n == 20 and after.s_falling < 9.5  # frozen baseline, CUSUM carries on
