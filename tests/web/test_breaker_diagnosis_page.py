"""The breaker page's "Diagnose the last N operations" (issue 20) in a real headless Chromium:
a reader signs in, asks for the diagnosis of the last 3 stored openings, and sees the answer
(where, which, how far, the corrected parameters) appear without a reload. The real diagnosis
runs; the test checks what is drawn, not whether the answer is right."""

from __future__ import annotations

from datetime import timedelta

import pytest

from .weblive import T0, PageLog, screenshot, sign_in, start_server, synth

VIEWPORT = {"width": 1400, "height": 900}
SNEAKY = '<img src=x onerror="document.title=1">'  # a key name that must show as text


@pytest.fixture(scope="module")
def live(tmp_path_factory, breaker, browser):
    app, stop = start_server(tmp_path_factory.mktemp("web-bdiag"), name=SNEAKY)
    try:
        for i in range(3):
            app.ingest(synth(breaker, "open", 700 + i, None, T0 + timedelta(minutes=10 * i)), "open")
        app.wait_fits()
        yield app
    finally:
        stop()


def test_reader_diagnoses_the_last_operations_and_sees_the_result(live, browser):
    context = browser.new_context(viewport=VIEWPORT)
    log = PageLog(context, live.base)
    try:
        page = sign_in(context, live, "reader", log)
        page.goto(f"{live.base}/breakers/1")
        page.wait_for_selector('body[data-ready="1"]', timeout=30000)
        assert page.locator("#bdiag-form").is_visible()
        page.fill("#bdiag-last", "3")
        page.select_option("#bdiag-operation", "open")
        page.click("#bdiag-submit")
        page.wait_for_url(f"{live.base}/breakers/1?diagnosis=*", timeout=30000)
        # shown while it runs, then swapped in by the live update when done
        page.wait_for_selector("#bdiag-status", timeout=240000)
        section = page.locator("#breaker-diagnosis")
        assert section.get_attribute("data-bdiag-status") == "done"
        assert "3 stored openings used of the last 3" in page.locator("#bdiag-summary").inner_text()
        status = page.locator("#bdiag-status").get_attribute("data-status")
        assert status in ("none", "named", "ambiguous", "unexplained", "explained", "partly_explained")
        # where: one bar per phase before the correction (four phases of an opening)
        assert section.locator("svg.bdiag-bars rect.bar-before").count() == 4
        # how far: the gap before is a number of mrad, not a dash
        before = page.locator("#bdiag-before").inner_text().strip()
        assert before != "—" and float(before) > 0
        # which: the probabilities table when the result carries them, else the named effects
        probs = section.locator("table.bdiag-probs tbody tr").count()
        assert probs >= 2 or "No probabilities" in section.inner_text()
        # the key's name (who asked) is shown as text, never as markup
        head = page.locator("#bdiag-head")
        assert SNEAKY in head.inner_text() and head.locator("img").count() == 0
        assert page.title() != "1"
        # the docs' screenshot shows an engineer's name, not this test's markup
        from sqlalchemy import update

        from service.storage import crud
        from service.storage.models import BreakerDiagnosisRow

        with live.Session() as s, s.begin():
            s.execute(update(BreakerDiagnosisRow).values(requested_by="engineer"))
            live.keys["engineer"] = crud.create_api_key(s, name="engineer", role="reader")[1]
        shown = browser.new_context(viewport=VIEWPORT)
        try:
            clean_page = sign_in(shown, live, "engineer")
            clean_page.goto(page.url)
            clean_page.wait_for_selector("#bdiag-status", timeout=30000)
            assert "engineer" in clean_page.locator("#bdiag-head").inner_text()
            screenshot(clean_page, "breaker-diagnosis")
        finally:
            shown.close()
        assert log.errors == [], log.errors
        assert log.foreign() == []
    finally:
        context.close()


def test_out_of_range_n_is_refused_in_words(live, browser):
    context = browser.new_context(viewport=VIEWPORT)
    try:
        page = sign_in(context, live, "reader")
        page.goto(f"{live.base}/breakers/1")
        csrf = page.eval_on_selector('#bdiag-form input[name="csrf_token"]', "e => e.value")
        r = context.request.post(f"{live.base}/breakers/1/diagnoses",
                                 form={"csrf_token": csrf, "operation": "open", "last": "50"},
                                 headers={"Origin": live.base})
        assert r.status == 422 and "last" in r.text()
        r = context.request.post(f"{live.base}/breakers/1/diagnoses", form={"operation": "open", "last": "3"},
                                 headers={"Origin": live.base})
        assert r.status == 403  # no CSRF token
    finally:
        context.close()
