"""The condition report is drawn by a worker, never in the API's threads (issue 44 item 2): the API
answers with the job (202, its URL in Location) or the PDF when the worker is done within
``[server] report_wait_s``; the job's URL gives the PDF; the web page's button still downloads it.
The light routes' latency while reports are drawn is measured in bench/reports_under_load.py."""

from __future__ import annotations

import re
import time

import pytest

from service.storage import crud
from tests.conftest import BREAKER_FILE
from tests.service.conftest import make_settings, running_app

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


@pytest.fixture(params=[0.0, 30.0], ids=["answer-at-once", "wait-for-the-pdf"])
def svc(request, tmp_path):
    from service.storage.db import upgrade

    (tmp_path / "data").mkdir()
    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    upgrade(url)
    settings = make_settings(tmp_path, url, server={"auth_free_failures": 100_000, "report_wait_s": request.param})
    with running_app(settings) as (app, client, keys):
        with app.state.Session() as s, s.begin():
            crud.register_breaker_file(s, path=BREAKER_FILE, tag="Q1")
        yield app, client, {"X-API-Key": keys["reader"]}, request.param


def _until_done(client, url, h, limit_s=120.0):
    deadline = time.monotonic() + limit_s
    while True:
        r = client.get(url, headers=h)
        if r.status_code != 202 or time.monotonic() > deadline:
            return r
        assert r.json()["status"] in ("queued", "running", "done")
        time.sleep(0.1)


def test_asking_for_a_report_answers_at_once_with_the_job_whose_url_gives_the_pdf(svc):
    app, client, h, _ = svc
    r = client.post("/api/v1/breakers/Q1/reports", headers=h)
    assert r.status_code == 202
    job = r.json()
    assert r.headers["Location"] == job["url"] == f"/api/v1/reports/{job['id']}"
    assert job["breaker"] == "reference-252kV" and job["status"] in ("queued", "running", "done")
    pdf = _until_done(client, job["url"], h)
    assert pdf.status_code == 200 and pdf.content[:5] == b"%PDF-"
    assert "reference-252kV" in pdf.headers["Content-Disposition"]


def test_the_report_route_gives_the_pdf_or_the_job_when_it_is_not_ready_in_time(svc):
    app, client, h, wait = svc
    r = client.get("/api/v1/breakers/reference-252kV/report", headers=h)
    if wait == 0.0:  # nothing waits: the job comes back at once
        assert r.status_code == 202 and r.headers["Location"] == r.json()["url"]
        r = _until_done(client, r.json()["url"], h)
    assert r.status_code == 200 and r.content[:5] == b"%PDF-"


def test_an_unknown_or_malformed_job_is_refused_in_words(svc):
    app, client, h, _ = svc
    r = client.get("/api/v1/reports/" + "0" * 32, headers=h)
    assert r.status_code == 404 and "no report job" in r.json()["detail"]
    assert client.get("/api/v1/reports/not-a-job", headers=h).status_code == 422
    assert client.get("/api/v1/reports/" + "0" * 32).status_code == 401
    assert client.post("/api/v1/breakers/nosuch/reports", headers=h).status_code == 404


def test_the_same_report_asked_for_while_it_is_drawn_is_one_job(svc):
    app, client, h, _ = svc
    runner = app.state.reports
    a = runner.submit(breaker_id=1, breaker_name="reference-252kV")
    b = runner.submit(breaker_id=1, breaker_name="reference-252kV")
    assert a is b or a.future.done()
    assert a.future.result(120)[0][:5] == b"%PDF-"


def test_the_web_pages_report_button_still_downloads_the_pdf(svc):
    app, client, h, _ = svc
    form = client.get("/signin")
    token = re.search(r'name="csrf_token" value="([^"]+)"', form.text).group(1)
    assert client.post("/signin", data={"api_key": h["X-API-Key"], "csrf_token": token, "next": "/"},
                       follow_redirects=False).status_code == 303
    r = client.get("/breakers/1/report.pdf")
    assert r.status_code == 200 and r.content[:5] == b"%PDF-"


def test_too_many_waiting_reports_are_refused_in_words_not_queued(svc, monkeypatch):
    import threading

    from service.workers import reports as R

    app, client, h, _ = svc
    gate = threading.Event()
    monkeypatch.setattr(R, "MAX_PENDING", 2)
    monkeypatch.setattr(R, "draw_report", lambda *a, **k: (gate.wait(60), (b"%PDF-", "x"))[1])
    try:
        assert client.post("/api/v1/breakers/Q1/reports", params={"from": "2026-01-01"}, headers=h).status_code == 202
        assert client.post("/api/v1/breakers/Q1/reports", params={"from": "2026-01-02"}, headers=h).status_code == 202
        r = client.post("/api/v1/breakers/Q1/reports", params={"from": "2026-01-03"}, headers=h)
        assert r.status_code == 503 and "wait their turn" in r.json()["detail"] and r.headers["Retry-After"]
    finally:
        gate.set()


def test_hvcb_report_asks_the_running_service_and_writes_its_pdf(svc, tmp_path, capsys):
    """``hvcb report`` with a service answering: the PDF is the one its workers drew (the page's
    button), polled through 202 when it is not ready at once; a refused key is said in words."""
    from service.cli import main
    from tests.live_server import LiveServer

    app, client, h, _ = svc
    out = tmp_path / "from-service.pdf"
    with LiveServer(app, name="hvcb-report-cli") as server:
        assert main(["report", "Q1", "-o", str(out), "--url", server.url, "--key", h["X-API-Key"]]) == 0
        said = capsys.readouterr().out
        assert f"drawn by the service at {server.url}" in said
        assert out.read_bytes()[:5] == b"%PDF-"
        assert main(["report", "Q1", "-o", str(out), "--url", server.url, "--key", "not-a-key"]) == 2
        err = capsys.readouterr().err
        assert f"the service at {server.url} refused the report (401)" in err and "--key" in err
        assert main(["report", "Q9", "-o", str(out), "--url", server.url, "--key", h["X-API-Key"]]) == 2
        assert "refused the report (404)" in capsys.readouterr().err
    # Gone: with --url named, no fallback to a database the user did not ask for.
    assert main(["report", "Q1", "-o", str(out), "--url", server.url, "--key", h["X-API-Key"]]) == 2
    assert f"no service answers at {server.url}" in capsys.readouterr().err
