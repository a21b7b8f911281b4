"""The breaker page's report and export buttons in a real headless Chromium: a reader downloads
the condition report (a PDF of this breaker), the operations CSV (every stored operation) and,
with a date window, the alarm history; the files are the same as the API's."""

from __future__ import annotations

import csv
import io
import shutil
import subprocess
from datetime import timedelta

import pytest

from .weblive import BREAKER_FILE, PageLog, start_server

VIEWPORT = {"width": 1400, "height": 900}
N_OPS = 120


@pytest.fixture(scope="module")
def live(tmp_path_factory, browser):
    from service.breaker_file import load_breaker
    from tests.reports.history import bulk_history

    app, stop = start_server(tmp_path_factory.mktemp("web-reports"))
    try:
        bulk_history(app.Session, app.app.state.settings.drift_settings, load_breaker(BREAKER_FILE),
                     capture_path="/nonexistent.cfg", n=N_OPS, leak_from=0.5, leak_per_op=0.97)
        yield app
    finally:
        stop()


def _download(page, selector: str):
    with page.expect_download(timeout=60000) as info:
        page.click(selector)
    d = info.value
    return d.suggested_filename, open(d.path(), "rb").read()


def test_a_reader_downloads_the_report_and_the_exports_from_the_breaker_page(live, browser):
    from .weblive import sign_in

    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    log = PageLog(context, live.base)
    try:
        page = sign_in(context, live, "reader", log)
        page.goto(f"{live.base}/breakers/1")
        page.wait_for_selector('body[data-ready="1"]', timeout=30000)
        assert page.locator("#breaker-reports").is_visible()
        name, pdf = _download(page, "#report-pdf")
        assert name == "reference-252kV-condition-report.pdf" and pdf[:5] == b"%PDF-"
        if shutil.which("pdftotext"):
            text = subprocess.run(["pdftotext", "-raw", "-", "-"], input=pdf, capture_output=True, check=True).stdout
            assert b"Condition report: reference-252kV" in text and b"operating time" in text
        name, body = _download(page, "#export-operations")
        rows = list(csv.DictReader(io.StringIO(body.decode("utf-8"))))
        assert name == "reference-252kV-operations.csv" and len(rows) == N_OPS
        from service.reports.exports import operation_chunks

        assert body.decode("utf-8") == "".join(operation_chunks(live.Session, breaker_id=1))  # the API's file
        # a window: the alarms raised in it (all of them: the bulk history's alarms are raised now)
        from service.storage.models import utcnow

        today = utcnow().date()
        page.fill("#report-from", (today - timedelta(days=1)).isoformat())
        page.fill("#report-to", today.isoformat())
        name, body = _download(page, "#export-alarms")
        alarms = list(csv.DictReader(io.StringIO(body.decode("utf-8"))))
        from service.storage import crud

        with live.Session() as s:
            stored = crud.list_alarms(s, state="all", breaker_id=1)
        assert name == "reference-252kV-alarms.csv" and stored
        assert sorted(int(a["alarm_id"]) for a in alarms) == sorted(a.id for a in stored)
        # an empty window before the history: the operations CSV holds the header only
        page.fill("#report-from", "2001-01-01")
        page.fill("#report-to", "2001-01-02")
        _, body = _download(page, "#export-operations")
        assert body.decode().count("\r\n") == 1 and body.startswith(b"operation_id,")
        assert log.errors == [], log.errors
        assert log.foreign() == []
    finally:
        context.close()
