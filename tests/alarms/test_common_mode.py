"""The temperature slope's error is common to every fit: the CUSUM's reference absorbs it
(service.alarms.drift.update, DriftSettings.common_mode_z). bench/alarm_rates.py measures the
effect on the seasonal false-alarm rates and the detection delays."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np

from service.alarms import DriftSettings, DriftState, FitObservation, update

T0 = datetime(2025, 1, 1, tzinfo=timezone.utc)


def compensated_state(settings: DriftSettings, seed: int = 3) -> tuple[DriftState, int]:
    rng = np.random.default_rng(seed)
    state = DriftState.new("DO", settings)
    for i in range(40):  # a baseline spanning -10..30 C, DO -0.4 %/K
        t = float(rng.uniform(-10, 30))
        v = 39.5 * (1 - 0.004 * (t - 20)) * (1 + 0.01 * rng.standard_normal())
        state, _ = update(state, FitObservation(operation_id=i + 1, time=T0 + timedelta(days=i), value=v,
                                                ci95=(v - 0.4, v + 0.4), temperature=t), settings)
    return state, 40


def after(state, settings, i, temperature, sigmas):
    """The falling CUSUM after a fit ``sigmas`` independent sds below the prediction."""
    m = state.model
    expected, var = m.predict(temperature, 0.4 / 1.96)
    ind = np.sqrt(var - m.slope_var * (temperature - m.t_mean) ** 2)
    v = expected - sigmas * ind
    obs = FitObservation(operation_id=i + 1, time=T0 + timedelta(days=i), value=float(v), ci95=(v - 0.4, v + 0.4),
                         temperature=temperature)
    return update(state, obs, settings)[0].s_falling


def test_the_reference_grows_with_the_distance_from_the_window_temperature():
    plain, absorbing = DriftSettings(common_mode_z=0.0), DriftSettings()
    state, i = compensated_state(absorbing)
    assert state.model.compensated and state.model.slope_var > 0 and state.s_falling == 0.0
    far = state.model.t_mean + 30.0
    # At the window's mean temperature there is no common-mode term: the same increment.
    at_mean = [after(state, s, i, state.model.t_mean, 2.5) for s in (plain, absorbing)]
    assert at_mean[0] > 0 and abs(at_mean[0] - at_mean[1]) < 1e-9
    # Far from it, the slope's error could explain part of the deviation: a smaller increment,
    # by common_mode_z sds of the slope's error times the distance, in score units.
    m = state.model
    expected, var = m.predict(far, 0.4 / 1.96)
    common = np.sqrt(m.slope_var) * 30.0
    ind = np.sqrt(var - common ** 2)
    s_plain, s_abs = after(state, plain, i, far, 2.5), after(state, absorbing, i, far, 2.5)
    assert s_abs < s_plain
    assert abs((s_plain - s_abs) - absorbing.common_mode_z * common / ind) < 1e-9
