"""The operation page of an uploaded close–open analyser record (issue 33) in a real headless
Chromium: the coil currents drawn under the travel on one time axis with the command and the
contact instant marked, the DCRM, and the analyser's own figures beside hvcb's with the
differences. The upload goes over the API, as a utility's would."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

from tests.analyser.export_gen import Spec, export_text

from .weblive import PageLog, canvas_ink, screenshot, sign_in, start_server

REPO = Path(__file__).resolve().parents[2]
VIEWPORT = {"width": 1400, "height": 1000}


@pytest.fixture(scope="module")
def live(tmp_path_factory, browser):
    from service.storage import crud

    app, stop = start_server(tmp_path_factory.mktemp("web-record"))
    try:
        with app.Session() as s, s.begin():
            bid = crud.register_breaker_file(s, path=REPO / "config/breakers/generic-analyser.toml", tag="R33").id
        r = httpx.post(f"{app.base}/api/v1/breakers/{bid}/captures", headers={"X-API-Key": app.keys["operator"]},
                       files=[("files", ("co.csv", export_text(Spec())[0].encode()))], timeout=120)
        assert r.status_code == 202, r.text
        app.ops = {o["operation"]: o["operation_id"] for o in r.json()["operations"]}
        app.wait_fits()
        yield app
    finally:
        stop()


@contextmanager
def operation_page(browser, live, op_id):
    """The operation page signed in as a reader, its channels drawn; no console error after."""
    context = browser.new_context(viewport=VIEWPORT)
    log = PageLog(context, live.base)
    try:
        sign_in(context, live, "reader", log).goto(f"{live.base}/operations/{op_id}")
        page = context.pages[-1]
        # app.js has drawn the travel and record_channels.js the recorded channels
        page.wait_for_selector('body[data-ready="1"] #record-channels:not([hidden])', timeout=30000)
        yield page
        assert log.errors == [], log.errors
        assert log.foreign() == []
    finally:
        context.close()


def test_opening_shows_coil_currents_dcrm_and_the_analysers_figures(live, browser):
    with operation_page(browser, live, live.ops["open"]) as page:
        for chart in ("record-travel", "coils", "dcrm"):
            assert canvas_ink(page, f'[data-chart="{chart}"]') > 500, chart
        # one time axis: the coil chart spans the travel chart's milliseconds
        spans = page.evaluate("""() => ['record-travel', 'coils'].map(k => {
            const u = window.hvcbRecord.charts[k]; return [u.scales.x.min, u.scales.x.max]; })""")
        assert spans[0] == spans[1] and spans[0][1] > spans[0][0]
        legend = page.locator('[data-chart="coils"]').inner_text()
        assert "C4 [A]" in legend and "C1 [A]" in legend
        events = page.locator("#record-events").inner_text()
        assert "command at" in events and "contact part at" in events and "DCRM R1" in events
        rows = {r.locator("td").nth(0).inner_text(): [r.locator("td").nth(k).inner_text() for k in range(1, 6)]
                for r in page.locator("#analyser-comparison tbody tr").all()}
        # the export states a rebound of 1.50 mm and an opening velocity of 5.90 m/s for T1
        assert rows["rebound"][:3] == ["mm", "T1", "1.500"] and rows["speed"][:3] == ["m/s", "T1", "5.900"]
        hvcb, diff = float(rows["speed"][3]), float(rows["speed"][4])
        assert diff == pytest.approx(hvcb - 5.9, abs=2e-3)
        assert page.locator("#contact-word").inner_text() == "contact part"
        screenshot(page, "operation-record-channels")


def test_closing_of_the_same_record_marks_contact_touch(live, browser):
    with operation_page(browser, live, live.ops["close"]) as page:
        assert canvas_ink(page, '[data-chart="coils"]') > 500
        assert "contact touch at" in page.locator("#record-events").inner_text()
        # the closing's fit fails (no cam table): no hvcb figures, so no comparison is shown
        assert page.locator("#comparison-block").is_hidden()
