"""The web page in a real headless Chromium: sign-in, fleet, breaker charts, operation curves and
diagnosis, alarm acknowledgement by role, live updates; no console error, no foreign request."""

from __future__ import annotations

from datetime import timedelta

import httpx
import pytest
from sqlalchemy import select

from .weblive import (T0, PageLog, canvas_ink, csrf_of, history, screenshot, sign_in, start_server,
                      synth)

VIEWPORT = {"width": 1400, "height": 900}


@pytest.fixture(scope="module")
def live(tmp_path_factory, breaker, browser):
    app, stop = start_server(tmp_path_factory.mktemp("web"))
    try:
        for kind, cap in history(breaker):
            app.ingest(cap, kind)
        from .weblive import BREAKER_FILE

        from service.storage import crud

        with app.Session() as s, s.begin():  # a second bay, commissioned, nothing recorded yet
            text = BREAKER_FILE.read_text().replace('name = "reference-252kV"', 'name = "bay-2 252kV"')
            cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
            crud.upsert_breaker(s, name="bay-2 252kV", tag="Q2", breaker_file=text,
                                cam_file_name="reference-252kV.cam.csv", cam_table=cam)
        app.wait_fits()
        yield app
    finally:
        stop()


@pytest.fixture
def ctx(browser, live):
    context = browser.new_context(viewport=VIEWPORT)
    log = PageLog(context, live.base)
    yield context, log
    context.close()


def clean(log: PageLog) -> None:
    assert log.errors == [], log.errors
    assert log.foreign() == [], f"requests to other hosts: {log.foreign()}"
    assert log.requests, "no request was seen at all"


def api(live, path: str, role: str = "reader"):
    r = httpx.get(live.base + path, headers={"X-API-Key": live.keys[role]}, timeout=30)
    assert r.status_code == 200, r.text
    return r.json()


def test_sign_in_then_the_fleet_shows_the_breaker_with_its_status(live, ctx):
    context, log = ctx
    from service.storage import crud

    with live.Session() as s, s.begin():  # what the acquisition side reports for the DAQ link
        crud.report_daq(s, breaker_id=1, connected=True, frames=52_000, frames_dropped=3, crc_errors=1, captures=15)
    first = log.watch(context.new_page())
    first.goto(live.base + "/signin")
    screenshot(first, "signin")
    first.close()
    page = sign_in(context, live, "reader", log)
    health = api(live, "/api/v1/breakers/1/health")
    assert health["status"] in ("warning", "alarm")  # the leak in the history has raised the DO alarm
    row = page.locator('tr[data-breaker-id="1"]')
    assert row.locator(".breaker-name").inner_text() == "reference-252kV"
    badge = row.locator("[data-status]")
    assert badge.inner_text().strip().lower() == health["status"]
    assert health["status"] in badge.get_attribute("class")  # the status colour class
    assert row.locator("svg.spark polyline").count() == 2  # DO and BO sparklines
    assert "DO" in row.inner_text()
    daq = row.locator("td").last.inner_text()
    assert "connected" in daq and "dropped 3" in daq and "CRC 1" in daq
    other = page.locator('tr[data-breaker-id="2"]')
    assert other.locator("[data-status]").inner_text().strip().lower() == "unknown"
    assert "no fit yet" in other.inner_text() and "no DAQ reported" in other.inner_text()
    # the session cookie is HttpOnly and SameSite=Strict; the key is nowhere in the page or URL
    (cookie,) = [c for c in context.cookies() if c["name"] == "hvcb_session"]
    assert cookie["httpOnly"] and cookie["sameSite"] == "Strict"
    assert live.keys["reader"] not in page.content() and live.keys["reader"] not in page.url
    assert page.evaluate("() => localStorage.length + sessionStorage.length") == 0
    assert not page.evaluate("() => document.cookie.includes('hvcb_session')")
    # the API docs are served from the app's own vendored Swagger UI: they render offline
    docs = log.watch(context.new_page())
    docs.goto(live.base + "/docs")
    docs.wait_for_selector(".swagger-ui .info .title", timeout=30000)
    assert "hvcb" in docs.locator(".swagger-ui .info .title").inner_text()
    assert docs.locator(".opblock").count() > 10  # the operations were read from /openapi.json
    assert any(u.endswith("/static/vendor/swagger-ui/swagger-ui-bundle.js") for u in log.requests)
    clean(log)


def test_breaker_page_draws_every_chart(live, ctx):
    context, log = ctx
    page = sign_in(context, live, "reader", log)
    page.click('a.breaker-name:has-text("reference-252kV")')
    page.wait_for_selector('body[data-ready="1"]', timeout=30000)
    for name in ("AO", "BO", "DO", "EO", "AC", "BC", "CC"):
        assert canvas_ink(page, f'[data-chart="param-{name}"]') > 500, name
    for name in ("DO", "BO"):
        assert canvas_ink(page, f'[data-chart="drift-{name}"]') > 500, f"drift {name}"
    for key in ("operating_time_s", "average_speed_rad_s", "overtravel_rad", "rebound_rad"):
        assert canvas_ink(page, f'[data-chart="char-{key}"]') > 500, key
    # the legend names the band and the baseline; the operations are listed
    legend = page.locator('[data-chart="param-DO"] .u-legend').inner_text()
    assert "DO" in legend and "95 % CI" in legend and "baseline mean" in legend and "lower" not in legend
    assert page.locator("#operations tr[data-operation-id]").count() == 15
    clean(log)


def test_operation_page_shows_curve_residual_and_diagnosis(live, ctx):
    context, log = ctx
    page = sign_in(context, live, "reader", log)
    with live.Session() as s:
        from service.storage.models import OperationRow

        op_id = s.scalar(select(OperationRow.id).where(OperationRow.kind == "open")
                         .order_by(OperationRow.id.desc()).limit(1))
    page.goto(f"{live.base}/operations/{op_id}")
    page.wait_for_selector('body[data-ready="1"]', timeout=30000)
    assert canvas_ink(page, '[data-chart="travel"]') > 2000
    assert canvas_ink(page, '[data-chart="residual"]') > 2000
    assert canvas_ink(page, '[data-chart="vibration"]') > 2000
    legend = page.locator('[data-chart="travel"] .u-legend').inner_text()
    assert "measured" in legend and "fitted model" in legend
    assert "±2σ band: the " in page.locator('[data-chart="residual"] .u-legend').inner_text()  # which noise it shows
    assert page.locator("table.params td.strong", has_text="DO").count() == 1
    # the download link serves the COMTRADE pair
    with page.expect_download() as dl:
        page.click("#download")
    assert dl.value.suggested_filename == f"operation-{op_id}.zip"
    # request the diagnosis; it shows without a reload when done
    page.click("#diagnose")
    page.wait_for_selector("#verdict", timeout=120000)
    verdict = page.locator("#verdict").inner_text()
    assert verdict
    assert page.locator("table.candidates tbody tr").count() >= 3
    assert page.locator("svg.bars rect.bar-before").count() == 4  # four phases of an opening (bars before; after when corrected)
    clean(log)


def test_operator_acknowledges_an_alarm_and_a_reader_cannot(live, browser):
    alarms = api(live, "/api/v1/alarms?state=active")
    raised = [a for a in alarms if a["state"] == "raised"]
    assert raised, alarms
    alarm_id = raised[0]["id"]

    reader = browser.new_context(viewport=VIEWPORT)
    log = PageLog(reader, live.base)
    page = sign_in(reader, live, "reader", log)
    page.goto(live.base + "/alarms")
    assert page.locator(f'[data-alarm-id="{alarm_id}"]').count() == 1
    assert page.locator("[data-ack]").count() == 0  # no button for a reader
    assert page.locator("text=Reset baseline").count() == 0
    r = reader.request.post(f"{live.base}/alarms/{alarm_id}/ack", form={"csrf_token": csrf_of(page)},
                            max_redirects=0)
    assert r.status == 403
    clean(log)
    reader.close()

    operator = browser.new_context(viewport=VIEWPORT)
    log = PageLog(operator, live.base)
    page = sign_in(operator, live, "operator", log)
    page.goto(live.base + "/alarms")
    card = page.locator(f'[data-alarm-id="{alarm_id}"]')
    assert "baseline" in card.inner_text().lower()  # the evidence is shown
    card.locator('input[name="comment"]').fill("buffer inspection booked")
    card.locator("[data-ack]").click()
    page.wait_for_selector(f'[data-alarm-id="{alarm_id}"][data-state="acknowledged"]')
    assert "buffer inspection booked" in page.locator(f'[data-alarm-id="{alarm_id}"]').inner_text()
    assert page.locator("text=Reset baseline…").count() == 0  # admin only
    clean(log)
    operator.close()
    (after,) = [a for a in api(live, "/api/v1/alarms?state=all") if a["id"] == alarm_id]
    assert after["state"] == "acknowledged" and after["acknowledged_by"] == "web-operator"


def test_a_new_operation_appears_without_a_reload(live, ctx, breaker):
    context, log = ctx
    page = sign_in(context, live, "reader", log)
    page.goto(live.base + "/breakers/1")
    page.wait_for_selector('body[data-ready="1"]')
    page.evaluate("() => { window.__sameDocument = 42; }")
    before = page.locator("#operations tr[data-operation-id]").count()
    new_id = live.ingest(synth(breaker, "open", 999, None, T0 + timedelta(days=1)), "open")
    page.wait_for_selector(f'#operations tr[data-operation-id="{new_id}"] .fit-done', timeout=60000)
    assert page.evaluate("() => window.__sameDocument") == 42  # the same document: no reload
    assert page.locator("#operations tr[data-operation-id]").count() == min(before + 1, 50)
    assert int(page.get_attribute("body", "data-live-updates")) >= 1
    clean(log)


def test_upload_page_is_for_operators_and_shows_the_fit(live, browser, tmp_path, breaker):
    from service.acquisition.comtrade_writer import write_comtrade

    reader = browser.new_context(viewport=VIEWPORT)
    page = sign_in(reader, live, "reader")
    assert page.locator('nav a[href="/upload"]').count() == 0
    assert page.goto(live.base + "/upload").status == 403
    reader.close()

    context = browser.new_context(viewport=VIEWPORT)
    log = PageLog(context, live.base)
    page = sign_in(context, live, "operator", log)
    page.click('nav a[href="/upload"]')
    screenshot(page, "upload")
    cfg = write_comtrade(synth(breaker, "open", 4242, None, T0 + timedelta(days=2)), tmp_path / "up", "upload-me")
    page.set_input_files('input[name="files"]', [str(cfg), str(cfg.with_suffix(".dat"))])
    page.click('#upload-form button[type="submit"]')
    page.wait_for_url(f"{live.base}/operations/*", timeout=120000)  # the upload is parsed and stored first
    page.wait_for_selector('#op-summary[data-fit-status="done"]', timeout=60000)
    page.wait_for_function("() => document.querySelector('[data-chart=\"residual\"] canvas') !== null", timeout=60000)
    assert page.locator("table.params td.strong", has_text="BO").count() == 1
    clean(log)
    context.close()
