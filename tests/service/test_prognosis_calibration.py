"""The calibration's state in the database (service.jobs.prognosis): scored on every fit, also
between two refreshes; carried into the next refresh; restarted by a logged repair."""

from __future__ import annotations

from datetime import timedelta

import numpy as np

from service.jobs import prognosis as job
from service.storage.models import PrognosisRow
from tests.service.test_prognosis_refresh import T0, _store_flat


def _state(env, parameter="DO") -> dict:
    with env.Session() as s:
        row = s.get(PrognosisRow, (1, parameter))
        return dict(row.result).get(job.CALIBRATION) or {}


def _as_of(env):
    with env.Session() as s:
        return dict(s.get(PrognosisRow, (1, "DO")).result)["as_of"]


def test_every_fit_is_scored_and_the_state_survives_a_new_session(env):
    rng = np.random.default_rng(8)
    _store_flat(env, 0, 100, rng=rng)
    assert _state(env)["forecasts"]  # the prognosis left its forecast
    quiet = 0
    for i in range(100, 110):
        before, as_of = _state(env), _as_of(env)
        _store_flat(env, i, i + 1, rng=rng)
        after = _state(env)
        assert after["fits"] == before["fits"] + 1  # scored, refreshed or not
        if _as_of(env) == as_of:  # not due: scored all the same, against every pending forecast
            quiet += 1
            n = lambda st: sum(b["n"] for b in st["bands"].values())
            assert n(after) == n(before) + len(before["forecasts"]) and after["forecasts"] != before["forecasts"]
    assert quiet >= 5  # most of these fits were not due
    # the refresh reads the stored state (a new session, as after a worker restart) and adds its forecast
    with env.Session() as s, s.begin():
        job.store_prognoses(s, breaker_id=1, settings=env.settings.drift_settings, force={"DO"})
    forced = _state(env)
    assert forced["fits"] == after["fits"] and forced["bands"] == after["bands"]
    assert len(forced["forecasts"]) == min(len(after["forecasts"]) + 1, 4) and forced["forecasts"][-1]["seen"] == 0


def test_a_logged_repair_restarts_the_calibration(env):
    from service.jobs.maintenance import record_event

    rng = np.random.default_rng(9)
    _store_flat(env, 0, 100, rng=rng)
    assert _state(env)["key"] == "reset"
    with env.Session() as s, s.begin():
        record_event(s, breaker_id=1, kind="buffer refilled", done_at=T0 + timedelta(minutes=99, seconds=30),
                     done_by="test", recorded_by="test", settings=env.settings.drift_settings)
    _store_flat(env, 100, 101, rng=rng)
    st = _state(env)
    assert st["key"] != "reset" and st["fits"] == 0
