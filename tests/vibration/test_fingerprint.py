"""The breaker's healthy fingerprint and each operation's shift from it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivers.synthetic import synthesize_capture
from service.prototypes.a.trip_strike import add_trip_strike
from service.vibration import Fingerprint, vibration_characteristics
from service.vibration.fingerprint import envelope_lag


def _op(breaker, seed, latch_s, strike_g=30.0):
    rng = np.random.default_rng(seed)
    cap, truth = synthesize_capture(breaker, "open", breaker.design_parameters(), rng=rng)
    if latch_s is not None:
        cap = dataclasses.replace(cap, vibration=add_trip_strike(cap.vibration, cap.sample_rate, truth.t_motion,
                                                                 latch_s, rng, strike_g=strike_g))
    return vibration_characteristics(cap, "open", truth.t_motion, truth.t_peak)


@pytest.fixture(scope="module")
def fingerprint(breaker):
    healthy = [_op(breaker, s, 1.2e-3 + 0.02e-3 * (s % 3)) for s in range(6)]
    return Fingerprint("open").fit(healthy, operation_ids=list(range(6)))


def test_learns_each_event_and_the_latch_time(fingerprint):
    fp = fingerprint.to_dict()
    assert fp["count"] == 6
    assert fp["events"]["first_shock"]["t_s"] == pytest.approx(-1.22e-3, abs=0.1e-3)
    assert fp["events"]["latch_release"]["t_s"] == pytest.approx(-0.4e-3, abs=0.05e-3)
    assert fp["latch"]["mean_s"] == pytest.approx(1.22e-3, abs=0.1e-3)
    assert fp["latch"]["sd_s"] >= 0.05e-3
    env = fp["envelope"]
    assert env["dt_s"] == pytest.approx(0.25e-3) and len(env["mean_db"]) == len(env["sd_db"]) > 300


def test_a_slow_latch_shifts_from_the_fingerprint(breaker, fingerprint):
    healthy = fingerprint.shift(_op(breaker, 40, 1.21e-3))
    slow = fingerprint.shift(_op(breaker, 41, 2.5e-3))
    assert abs(healthy["latch_z"]) < 3
    assert slow["latch_shift_s"] == pytest.approx(1.29e-3, abs=0.15e-3) and slow["latch_z"] > 5
    assert slow["events"]["first_shock"]["shift_s"] < -1e-3
    assert healthy["envelope_correlation"] > 0.8
    assert healthy["strike_not_seen"] is None and slow["strike_not_seen"] is None


def test_a_missed_strike_is_named_not_read_as_a_short_latch(breaker, fingerprint):
    missed = fingerprint.shift(_op(breaker, 42, None))  # the release alone: the strike not seen
    assert missed["strike_not_seen"] and "not seen" in missed["strike_not_seen"]


def test_too_few_operations_refused(breaker):
    with pytest.raises(ValueError, match="3 healthy operations"):
        Fingerprint("open").fit([_op(breaker, 1, 1.2e-3)])


def test_envelope_lag_recovers_a_known_shift():
    t = np.arange(400) * 0.25e-3
    ref = 20 * np.log10(1 + 50 * np.exp(-((t - 0.03) / 1e-3) ** 2) + 20 * np.exp(-((t - 0.06) / 1e-3) ** 2))
    late = np.interp(t - 0.75e-3, t, ref)
    lag, corr = envelope_lag(late, ref, 0.25e-3)
    assert lag == pytest.approx(0.75e-3, abs=0.1e-3) and corr > 0.95
