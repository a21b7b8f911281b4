"""The stored prognosis is refreshed when it is due (service.jobs.prognosis.REFRESH_SHARE), not on
every fit, and the fit job commits the fit before its prognosis follows."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
from sqlalchemy import select

from service.jobs import prognosis as job
from service.jobs.fit import update_drift
from service.storage.models import PrognosisRow
from tests.fit_rows import store_fit

T0 = datetime.now(timezone.utc) - timedelta(days=2)


def _store_flat(env, first: int, last: int, *, rng) -> None:
    """Openings first..last-1 of breaker 1, one a minute: DO and BO flat, each fed to the drift
    update (and so its prognosis hook) as it lands."""
    for i in range(first, last):
        do = 39.5 * (1 + rng.normal(0, 0.003))
        with env.Session() as s, s.begin():
            store_fit(s, key=f"flat{i}", breaker_id=1, occurred_at=T0 + i * timedelta(minutes=1), result={
                "parameters": {"AO": 3424.0, "BO": 4806.0 * (1 + rng.normal(0, 0.002)), "DO": do, "EO": 3950.0},
                "ci95": {"DO": [do - 0.3, do + 0.3], "BO": [4790.0, 4822.0]}, "identifiable": True})
            update_drift(s, breaker_id=1, settings=env.settings.drift_settings)


def _stored(env) -> dict:
    with env.Session() as s:
        return {r.parameter: dict(r.result) for r in s.scalars(select(PrognosisRow))}


def _opening(as_of: dict) -> int:
    """The opening index of a stored prognosis's last fit (one a minute from T0)."""
    t = datetime.fromisoformat(as_of["time"])
    return round((t - T0).total_seconds() / 60)


def test_a_long_flat_history_is_refreshed_every_twentieth_of_its_length(env):
    rng = np.random.default_rng(5)
    _store_flat(env, 0, 100, rng=rng)
    seen = [_stored(env)["DO"]]
    for i in range(100, 140):
        _store_flat(env, i, i + 1, rng=rng)
        now = _stored(env)["DO"]
        if now["as_of"] != seen[-1]["as_of"]:
            seen.append(now)
    gaps = [_opening(b["as_of"]) - _opening(a["as_of"]) for a, b in zip(seen, seen[1:])]
    assert len(gaps) >= 3, gaps  # not never
    for a, gap in zip(seen, gaps):  # exactly when due: a twentieth of the history after the last
        q = (a.get("operations_to_limit") or {}).get("p05")
        span = min(a["history_fits"], q) if isinstance(q, (int, float)) else a["history_fits"]
        assert gap == max(1, int(span // job.REFRESH_SHARE)), (gaps, a["history_fits"], q)
    assert max(gaps) >= 5  # not on every fit: a history of 100 fits skips four in five


def test_an_edited_limit_refreshes_the_stored_prognosis_at_once(env):
    rng = np.random.default_rng(6)
    _store_flat(env, 0, 110, rng=rng)
    assert _opening(_stored(env)["DO"]["as_of"]) < 109  # the stored one is a few fits old (not due)
    with env.Session() as s:
        b = s.get(job.BreakerRow, 1)
        stored = s.get(PrognosisRow, (1, "DO"))
        limit = dict(job.limits_of(b).items())["DO"]
        assert not job.refresh_due(s, breaker=b, parameter="DO", limit=limit, settings=env.settings.drift_settings,
                                   stored=stored)
        stored.result = {**stored.result, "basis_key": "an older limit"}
        assert job.refresh_due(s, breaker=b, parameter="DO", limit=limit, settings=env.settings.drift_settings,
                               stored=stored)
    with env.Session() as s, s.begin():
        job.store_prognoses(s, breaker_id=1, settings=env.settings.drift_settings, force={"DO"})
    assert _opening(_stored(env)["DO"]["as_of"]) == 109  # forced: recomputed up to the latest fit


def test_a_fit_job_stores_its_fit_and_alarms_even_when_the_prognosis_fails(env, breaker, monkeypatch, caplog):
    from tests.service.conftest import synth

    def broken(*args, **kw):
        raise RuntimeError("the prognosis broke")

    monkeypatch.setattr(job, "store_prognoses", broken)
    res = env.app.state.monitor.ingest(synth(breaker, "open", 1), breaker_id=1, operation="open")
    env.wait_fits(1)
    o = env.client.get(f"/api/v1/operations/{res.operation_id}", headers=env.h("reader")).json()
    assert o["fit"]["status"] == "done", o["fit"]
    assert _stored(env) == {}  # no prognosis followed, and the log says why in words
    assert any("was not refreshed: the prognosis broke" in r.getMessage() for r in caplog.records)
