"""/api/v1/breakers/{name}/diagnoses (issue 20): queued in the worker pool, followed, listed and
persisted, on SQLite and PostgreSQL. A fast double of ``diagnose`` stands in where a test is about
the plumbing (it says nothing of diagnostic accuracy); the last test runs the real one on two
real stored captures."""

from __future__ import annotations

import threading
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from sqlalchemy import select

from conftest import make_settings, running_app, synth
from service.storage import crud
from service.storage.models import BreakerDiagnosisRow, CapturePreviewRow, OperationRow

T0 = datetime(2026, 10, 1, 6, 0, tzinfo=timezone.utc)
NAME = "reference-252kV"
URL = f"/api/v1/breakers/{NAME}/diagnoses"


def n_captures(result: dict) -> int:
    """The result's ``captures``: a count in the issue-20 shape, a list per capture before it."""
    c = result["captures"]
    return c if isinstance(c, int) else len(c)


class FakeDiagnose:
    """Records what it was given and answers in the shape of the real result. ``gate`` holds a
    job running until the test releases it."""

    def __init__(self, fail: str | None = None):
        self.calls: list[tuple[int, str, list]] = []
        self.gate = threading.Event()
        self.gate.set()
        self.fail = fail

    def __call__(self, captures, breaker, operation, *, seed=1, **kw):
        self.gate.wait(timeout=30)
        self.calls.append((len(captures), operation, [c.start_time for c in captures]))
        if self.fail:
            from service.diagnosis import DiagnosisError

            raise DiagnosisError(self.fail)
        return {"operation": operation, "captures": [{"source": c.source} for c in captures],
                "status": "named", "effects": ["viscous_friction"],
                "probabilities": {"none": 0.02, "viscous_friction": 0.95, "sensor_nonlinearity": 0.03},
                "rivals": [{"effect": "sensor_nonlinearity", "probability": 0.03}],
                "gap": {"before_rms_rad": 2e-3, "after_rms_rad": 1.1e-3, "noise_rad": 1e-3, "shrink": 0.9},
                "message": "fake: plumbing only", "nan_value": float("nan")}


class App:
    def __init__(self, app, client, keys):
        self.app, self.client, self.keys = app, client, keys

    def h(self, role="reader"):
        return {"X-API-Key": self.keys[role]}

    def store(self, kind: str, n: int, start: int = 0) -> list[int]:
        """n synthetic operations of ``kind``, 10 minutes apart, stored as the monitor stores them."""
        ids = []
        for i in range(start, start + n):
            cap = synth(self.breaker, kind, seed=500 + i, start_time=T0 + timedelta(minutes=10 * i))
            res = self.app.state.monitor.ingest(cap, breaker_id=1, operation=kind, source="upload")
            ids.append(res.operation_id)
        return ids

    def wait_fits(self, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while True:
            with self.app.state.Session() as s:
                if crud.queue_depth(s) == 0:
                    return
            assert time.monotonic() < deadline, "fits still pending"
            time.sleep(0.05)

    def wait(self, url: str, timeout: float = 60.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            r = self.client.get(url, headers=self.h())
            assert r.status_code == 200, r.text
            if r.json()["status"] in ("done", "failed"):
                return r.json()
            assert time.monotonic() < deadline, r.text
            time.sleep(0.1)


@pytest.fixture
def fake(monkeypatch):
    import service.diagnosis

    f = FakeDiagnose()
    monkeypatch.setattr(service.diagnosis, "diagnose", f)
    yield f
    f.gate.set()


@pytest.fixture
def svc(tmp_path, db_url, breaker):
    # fits fail at once: these tests are about diagnoses of stored captures, not about fits
    settings = make_settings(tmp_path, db_url, fit_function="fleet_helpers:no_fit")
    with running_app(settings) as (app, client, keys):
        out = App(app, client, keys)
        out.breaker = breaker
        yield out


def test_queue_follow_list_and_persist(svc, fake):
    opens = svc.store("open", 4)
    closes = svc.store("close", 1, start=10)
    assert svc.client.post(URL, json={"operation": "open", "last": 3}).status_code == 401
    r = svc.client.post(URL, json={"operation": "open", "last": 3}, headers=svc.h())
    assert r.status_code == 202, r.text
    body = r.json()
    assert r.headers["Location"] == body["url"] == f"/api/v1/breakers/1/diagnoses/{body['id']}"
    assert body["status"] in ("queued", "running", "done")
    assert body["operation_ids"] == opens[-3:] and body["used"] == 3 and body["skipped"] == []
    assert body["summary"].startswith("3 stored openings used of the last 3")
    done = svc.wait(r.headers["Location"])
    assert done["status"] == "done" and done["failure_reason"] is None
    assert done["diagnosis_status"] == "named" and done["effects"] == ["viscous_friction"]
    assert done["result"]["probabilities"]["viscous_friction"] == 0.95
    assert done["result"]["nan_value"] is None  # NaN stored as null (PostgreSQL's JSON has no NaN)
    assert done["result"]["operation_ids"] == opens[-3:]
    # the job got the three captures in time order, of the asked operation
    (n, kind, times), = fake.calls
    assert n == 3 and kind == "open" and times == sorted(times)
    # persisted: a new session reads the same result
    with svc.app.state.Session() as s:
        row = s.get(BreakerDiagnosisRow, body["id"])
        assert row.status == "done" and row.result["effects"] == ["viscous_friction"]
    # by id as well as by name
    assert svc.client.get(f"/api/v1/breakers/1/diagnoses/{body['id']}", headers=svc.h()).json()["id"] == body["id"]
    # an identical request answers with the same diagnosis, without running it again
    again = svc.client.post(URL, json={"operation": "open", "last": 3}, headers=svc.h("operator"))
    assert again.status_code == 200 and again.json()["id"] == body["id"] and again.json()["reused"]
    assert len(fake.calls) == 1
    # closings: fewer stored than asked, diagnosed with what there is, and said so
    c = svc.client.post(URL, json={"operation": "close", "last": 5}, headers=svc.h())
    assert c.status_code == 202 and c.json()["operation_ids"] == closes and c.json()["used"] == 1
    assert c.json()["summary"].startswith("1 stored closing used of the last 5")
    svc.wait(c.headers["Location"])
    listed = svc.client.get(URL, headers=svc.h())
    assert listed.status_code == 200
    assert [d["id"] for d in listed.json()] == [c.json()["id"], body["id"]]
    assert "result" not in listed.json()[0]


def test_bad_requests_say_what_is_wrong(svc, fake):
    svc.store("open", 2)
    for bad, words in (({"operation": "open", "last": 1}, "between 2 and 20"),
                       ({"operation": "open", "last": 21}, "between 2 and 20")):
        r = svc.client.post(URL, json=bad, headers=svc.h())
        assert r.status_code == 422 and words in r.json()["detail"], r.text
    r = svc.client.post(URL, json={"operation": "sideways", "last": 3}, headers=svc.h())
    assert r.status_code == 422 and "operation" in r.text
    r = svc.client.post(URL, json={"operation": "close", "last": 3}, headers=svc.h())
    assert r.status_code == 422 and "no stored closing" in r.json()["detail"]
    assert svc.client.post("/api/v1/breakers/nope/diagnoses", json={"operation": "open", "last": 2},
                           headers=svc.h()).status_code == 404
    assert svc.client.get(f"{URL}/999", headers=svc.h()).status_code == 404
    assert svc.client.get("/api/v1/breakers/nope/diagnoses", headers=svc.h()).status_code == 404
    assert fake.calls == []


def test_suspect_clocks_and_pruned_captures_are_left_out(svc, fake):
    opens = svc.store("open", 5)
    with svc.app.state.Session() as s, s.begin():
        from service.jobs.ingest import CLOCK_SUSPECT  # the flag ingest sets

        s.get(OperationRow, opens[-1]).flags = [CLOCK_SUSPECT]
        s.add(CapturePreviewRow(operation_id=opens[-2], preview={}))
        path = s.get(OperationRow, opens[-3]).capture_path
    for p in (Path(path), Path(path).with_suffix(".dat")):
        p.unlink(missing_ok=True)
    r = svc.client.post(URL, json={"operation": "open", "last": 2}, headers=svc.h())
    assert r.status_code == 202, r.text
    body = r.json()
    assert body["operation_ids"] == opens[:2] and body["used"] == 2
    assert [(x["operation_id"], x["reason"]) for x in body["skipped"]] == [
        (opens[-1], "its clock is suspect"), (opens[-2], "its raw capture was pruned by the retention policy"),
        (opens[-3], "its capture file is missing")]
    assert "3 newer left out" in body["summary"]
    assert svc.wait(body["url"])["status"] == "done"
    assert fake.calls[0][0] == 2


def test_a_failed_diagnosis_says_why_and_may_be_asked_again(svc, fake):
    svc.store("open", 2)
    fake.fail = "the captures are of different breakers"
    r = svc.client.post(URL, json={"operation": "open", "last": 2}, headers=svc.h())
    out = svc.wait(r.headers["Location"])
    assert out["status"] == "failed" and out["failure_reason"] == "the captures are of different breakers"
    assert out["result"] is None
    fake.fail = None
    again = svc.client.post(URL, json={"operation": "open", "last": 2}, headers=svc.h())
    assert again.status_code == 202 and again.json()["id"] != r.json()["id"]
    assert svc.wait(again.headers["Location"])["status"] == "done"


def test_a_row_left_queued_by_a_restart_runs_when_it_is_read(svc, fake):
    opens = svc.store("open", 2)
    with svc.app.state.Session() as s:  # as if the process that queued it had died
        from service.storage import crud_diagnoses

        key = crud_diagnoses.selection_key(breaker_id=1, kind="open", operation_ids=opens)
        row, created = crud_diagnoses.insert(s, breaker_id=1, kind="open", last=2, operation_ids=opens, skipped=[],
                                             key=key, requested_by="gone", key_id=None, role="reader")
        assert created
        rid = row.id
    out = svc.wait(f"{URL}/{rid}")
    assert out["status"] == "done" and fake.calls[0][0] == 2


@pytest.fixture
def sqlite_svc(tmp_path, breaker):
    from fastapi.testclient import TestClient

    from service.api.app import create_app
    from service.storage.db import upgrade

    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    (tmp_path / "data").mkdir()
    upgrade(url)
    # the local process pool, as `hvcb serve` runs it by default
    app = create_app(make_settings(tmp_path, url, executor="local", fit_function="fleet_helpers:no_fit"),
                     on_key=(shown := []).append)
    with TestClient(app) as client:
        with app.state.Session() as s, s.begin():
            reader = crud.create_api_key(s, name="test-reader", role="reader")[1]
        out = App(app, client, {"admin": shown[0], "reader": reader})
        out.breaker = breaker
        yield out


def test_the_real_diagnosis_runs_on_two_stored_captures(sqlite_svc, samples_dir):
    """Not a claim of accuracy: the real diagnose runs in the local process pool on real stored
    files and its answer is stored and served whole."""
    svc = sqlite_svc
    for name in ("open-nominal", "open-nominal-ascii"):
        files = [("files", (f"{name}{ext}", (samples_dir / f"{name}{ext}").read_bytes())) for ext in (".cfg", ".dat")]
        r = svc.client.post("/api/v1/breakers/1/captures", headers=svc.h("admin"), files=files,
                            data={"operation": "open"})
        assert r.status_code == 202, r.text
    r = svc.client.post(URL, json={"operation": "open", "last": 2}, headers=svc.h())
    assert r.status_code == 202, r.text
    out = svc.wait(r.headers["Location"], timeout=240)
    assert out["status"] == "done", out["failure_reason"]
    result = out["result"]
    assert result["operation"] == "open" and n_captures(result) == 2
    assert result["status"] in ("none", "named", "ambiguous", "unexplained", "explained", "partly_explained")
    assert result["gap"] and out["diagnosis_status"] == result["status"]
    with svc.app.state.Session() as s:
        assert s.scalar(select(BreakerDiagnosisRow.result).where(BreakerDiagnosisRow.id == out["id"]))["operation"] \
            == "open"


def test_identical_inserts_race_to_one_row_and_pending_captures_are_kept(svc, fake):
    """Two identical requests that both passed the lookup: the unique selection key lets one row
    in and hands the other the winner. While it is pending, retention keeps its captures."""
    from service.storage import crud_diagnoses
    from service.storage.retention import protected_operations

    opens = svc.store("open", 2)
    svc.wait_fits()  # (a pending fit protects them too)
    key = crud_diagnoses.selection_key(breaker_id=1, kind="open", operation_ids=opens)
    args = dict(breaker_id=1, kind="open", last=2, operation_ids=opens, skipped=[], key=key, requested_by="t",
                key_id=None, role="reader")
    with svc.app.state.Session() as s1, svc.app.state.Session() as s2:
        first, created1 = crud_diagnoses.insert(s1, **args)
        second, created2 = crud_diagnoses.insert(s2, **args)
        assert created1 and not created2 and second.id == first.id
        assert {i: why for i, why in protected_operations(s1).items() if i in opens} == \
            {i: "breaker diagnosis pending" for i in opens}
