"""Finding D12 of issue 25: any reader could queue breaker diagnoses without bound and hold the
worker pool. Now a reader key may have 2 queued or running, all reader keys together 4, an
operator 5 and an admin 10 (service/jobs/breaker_diagnosis.py says why); beyond that the answer
is 429 with Retry-After and a sentence, and an identical request reuses the existing diagnosis.

The diagnosis itself is a double held on a gate, so the queue stays full while the test asks.
"""

from __future__ import annotations

import threading
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
URL = "/api/v1/breakers/reference-252kV/diagnoses"


class HeldDiagnose:
    def __init__(self):
        self.gate = threading.Event()
        self.runs = 0

    def __call__(self, captures, breaker, operation, **kw):
        self.gate.wait(timeout=60)
        self.runs += 1
        return {"operation": operation, "status": "none", "effects": [], "captures": []}


@pytest.fixture
def held(monkeypatch):
    import service.diagnosis

    h = HeldDiagnose()
    monkeypatch.setattr(service.diagnosis, "diagnose", h)
    yield h
    h.gate.set()


@pytest.fixture
def svc(tmp_path):
    from fastapi.testclient import TestClient

    from service.acquisition.synthetic import synthesize_capture
    from service.api.app import create_app
    from service.breaker_file import load_breaker
    from service.settings import load_settings
    from service.storage import crud
    from service.storage.db import upgrade

    data = tmp_path / "data"
    data.mkdir()
    url = f"sqlite:///{data / 'hvcb.sqlite3'}"
    upgrade(url)
    settings = load_settings(data_dir=data, database_url=url, broker_url="", executor="inline",
                             bootstrap_admin_key=None, breakers=[REPO / "config/breakers/reference-252kV.toml"])
    shown = []
    app = create_app(settings, on_key=shown.append)
    breaker = load_breaker(REPO / "config/breakers/reference-252kV.toml")
    t0 = datetime(2026, 10, 1, tzinfo=timezone.utc)
    with TestClient(app) as client:
        keys = {"admin": shown[0]}
        with app.state.Session() as s, s.begin():
            for name, role in (("r1", "reader"), ("r2", "reader"), ("r3", "reader"), ("op", "operator")):
                keys[name] = crud.create_api_key(s, name=name, role=role)[1]
        # eight stored openings: "last 2", "last 3", ... select different operations
        p = breaker.design_parameters()
        for i in range(8):
            cap, _ = synthesize_capture(breaker, "open", p, rng=np.random.default_rng(900 + i))
            cap = type(cap)(**{**cap.__dict__, "start_time": t0 + timedelta(minutes=i)})
            app.state.monitor.ingest(cap, breaker_id=1, operation="open", source="upload")
        yield client, keys


def ask(client, keys, who, last):
    return client.post(URL, json={"operation": "open", "last": last}, headers={"X-API-Key": keys[who]})


def test_readers_are_bounded_with_429_and_identical_requests_reuse(svc, held):
    client, keys = svc
    first = ask(client, keys, "r1", 2)
    second = ask(client, keys, "r1", 3)
    assert first.status_code == second.status_code == 202
    # a third one from the same reader key is refused, in words, with when to ask again
    third = ask(client, keys, "r1", 4)
    assert third.status_code == 429, third.text
    assert int(third.headers["Retry-After"]) > 0
    assert "2 breaker diagnoses queued or running" in third.json()["detail"]
    assert "reader key" in third.json()["detail"]
    # the same request again is not a new diagnosis: no 429, the same id
    same = ask(client, keys, "r1", 2)
    assert same.status_code in (200, 202) and same.json()["id"] == first.json()["id"] and same.json()["reused"]
    # another reader key has its own two; then all readers together are at their bound of 4
    assert ask(client, keys, "r2", 5).status_code == 202
    assert ask(client, keys, "r2", 6).status_code == 202
    crowd = ask(client, keys, "r3", 7)
    assert crowd.status_code == 429 and "reader keys" in crowd.json()["detail"]
    assert "Retry-After" in crowd.headers
    # an operator is not held back by the readers
    assert ask(client, keys, "op", 7).status_code == 202
    # once the pool has worked through them, the reader may ask again
    held.gate.set()
    deadline = time.monotonic() + 30
    while True:
        r = client.get(URL, headers={"X-API-Key": keys["r1"]})
        if all(d["status"] == "done" for d in r.json()):
            break
        assert time.monotonic() < deadline, r.text
        time.sleep(0.1)
    assert held.runs == 5
    assert ask(client, keys, "r1", 4).status_code == 202


def test_concurrent_requests_of_one_reader_do_not_pass_the_bound_together(svc, held):
    client, keys = svc
    answers: list[int] = []
    threads = [threading.Thread(target=lambda n=n: answers.append(ask(client, keys, "r1", n).status_code))
               for n in range(2, 8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert sorted(answers) == [202, 202, 429, 429, 429, 429]
