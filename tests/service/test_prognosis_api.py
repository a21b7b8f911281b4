"""The prognosis over the REST API, stored by the worker's hook as each fit lands."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest
from sqlalchemy import select

from service.storage.models import BreakerRow, PrognosisRow
from tests.fit_rows import store_leak

URL = "/api/v1/breakers/{}/prognosis"


def test_leaking_breaker_gets_a_prognosis_with_quantiles(env):
    # DO falls 2 %/op from op 25, one a second: 25 % below baseline near op 39
    store_leak(env.Session, env.settings.drift_settings, t0=datetime.now(timezone.utc) - timedelta(hours=2),
               step=timedelta(seconds=1))
    r = env.client.get(URL.format("reference-252kV"), headers=env.h("reader"))
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["message"] == ""
    do = next(p for p in body["parameters"] if p["parameter"] == "DO")
    assert do["status"] == "ok" and do["direction"] == "falling" and do["basis"] == "change point"
    assert do["limit"] == pytest.approx(0.75 * do["baseline"])
    q = do["operations_to_limit"]
    # whole openings (issue 43): a steep leak's 5 % and median may be the same opening
    assert all(float(v).is_integer() for v in q.values())
    assert 0 < q["p05"] <= q["median"] <= q["p95"] and q["p05"] < q["p95"]
    assert 3 <= q["median"] <= 14  # the truth is about 8 more openings
    assert do["date_to_limit"] is None and do["rate_per_day"] is None  # a minute of operations: no rate
    assert len(do["fan"]["median"]) == len(do["fan"]["operations"]) > 10
    # BO is flat: "no trend", no median crossing, and the words say so with units
    bo = next(p for p in body["parameters"] if p["parameter"] == "BO")
    assert bo["status"] == "no trend" and (bo["operations_to_limit"] is None or bo["operations_to_limit"]["median"] is None)
    assert bo["summary"].startswith("Opening spring force (BO): no trend.") and "s⁻²" in bo["summary"]
    assert do["summary"].startswith("Buffer damping (DO) reaches its limit in about ") and "s⁻¹" in do["summary"]
    # ... and the worker stored the same median as the fits landed
    with env.Session() as s:
        rows = {r.parameter: r for r in s.scalars(select(PrognosisRow))}
    assert rows["DO"].median_operations == pytest.approx(q["median"], abs=0.1)
    assert rows["BO"].median_operations is None
    # the SCADA point (REST), Prometheus and the IEC 61850 view carry the soonest median
    env.client.app.state.scada_cache = None
    points = {p["point"]: p["value"] for p in env.client.get("/api/v1/scada/points", headers=env.h("reader")).json()}
    tag = next(k for k in points if k.endswith(".prognosis.operations_to_limit")).split(".")[0]
    assert points[f"{tag}.prognosis.operations_to_limit"] == pytest.approx(q["median"], abs=0.1)
    metrics = env.client.get("/metrics", headers=env.h("reader")).text
    line = next(x for x in metrics.splitlines() if x.startswith("hvcb_operations_to_limit{"))
    assert 'parameter="DO"' in line and float(line.split()[-1]) == pytest.approx(q["median"], abs=0.1)
    from service.iec61850.snapshot import OperatingTimeCache, breaker_views
    from service.storage.models import utcnow

    with env.Session() as s:
        view = breaker_views(s, now=utcnow(), daq_timeout_s=60, drift_settings=env.settings.drift_settings,
                             cache=OperatingTimeCache())[1]
    assert view.soonest[0] == "DO" and view.soonest[1] == pytest.approx(q["median"], abs=0.1)


def test_breaker_without_limits_is_told_how_to_add_them_and_unknown_is_404(env):
    with env.Session() as s, s.begin():
        b = s.scalar(select(BreakerRow))
        b.breaker_file = b.breaker_file.split("[limits]")[0]
    r = env.client.get(URL.format(1), headers=env.h("reader"))
    assert r.status_code == 200 and r.json()["parameters"] == []
    assert "[limits]" in r.json()["message"]
    r = env.client.get(URL.format("nope"), headers=env.h("reader"))
    assert r.status_code == 404
    assert env.client.get(URL.format(1)).status_code == 401


def test_prognosis_is_in_the_openapi_with_its_errors(env):
    spec = env.client.get("/openapi.json").json()
    op = spec["paths"]["/api/v1/breakers/{name}/prognosis"]["get"]
    assert {"200", "401", "403", "404"} <= set(op["responses"])


def test_the_prognosis_reads_a_bounded_window_of_the_newest_fits(env, monkeypatch):
    """The worker's prognosis cost per fit is bounded: it reads at most HISTORY_FITS fits, the
    newest, oldest first (service/jobs/prognosis.py)."""
    from service.jobs import prognosis as job

    monkeypatch.setattr(job, "HISTORY_FITS", 20)
    store_leak(env.Session, env.settings.drift_settings, t0=datetime.now(timezone.utc) - timedelta(hours=2),
               step=timedelta(seconds=1))
    with env.Session() as s:
        b = s.scalar(select(BreakerRow))
        hist = job._history(s, b, "DO")
        assert len(hist) == 20
        times = [o.time for o in hist]
        assert times == sorted(times)
        from service.storage import crud

        everything = crud.good_parameter_history(s, breaker_id=b.id, name="DO", since=b.baseline_reset_at)
        assert len(everything) == 32 and [o.operation_id for o in hist] == [r.operation_id for r in everything[-20:]]
        (do,) = [p for p in job.breaker_prognoses(s, breaker=b, settings=env.settings.drift_settings)
                 if p.parameter == "DO"]
        assert do.basis_operations <= 20 and do.status in ("ok", "crossed")
