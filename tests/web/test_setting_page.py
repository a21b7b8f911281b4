"""The operation page's spring setting (issue 39 item 3), in a real headless Chromium: for a
stored close–open pair, the nut steps with their 95 % interval beside the fitted parameters;
an operator records the unit's commissioning pair with the page's button, and the setting is
then read relative to it."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest

from tests.conftest import BREAKER_FILE
from tests.pair_rows import store_pair

from .weblive import PageLog, screenshot, sign_in, start_server

T0 = datetime(2026, 3, 1, 9, 0, tzinfo=timezone.utc)


@pytest.fixture(scope="module")
def live(tmp_path_factory, browser):
    from service.breaker_file import load_breaker
    from service.storage import crud

    app, stop = start_server(tmp_path_factory.mktemp("web-setting"))
    try:
        with app.Session() as s, s.begin():
            bid = crud.register_breaker_file(s, path=BREAKER_FILE, tag="SP1").id
        b = load_breaker(BREAKER_FILE)
        # a unit 1 % stiffer than the design: its pair at +1 step, and a pair at +3 steps a day later
        app.ref = store_pair(app.Session, b, breaker_id=bid, at=T0, steps=1.0, friction=1.02, kappa=1.01, key="r")
        app.later = store_pair(app.Session, b, breaker_id=bid, at=T0 + timedelta(days=1), steps=3.0,
                               friction=0.95, kappa=1.01, key="l")
        yield app
    finally:
        stop()


def _setting(page):
    box = page.locator("#spring-setting")
    return {"steps": box.locator("#setting-steps").inner_text(), "ci": box.locator("#setting-ci").inner_text(),
            "basis": box.locator("#setting-basis").inner_text()}


def test_the_setting_beside_the_fitted_parameters_and_the_commissioning_button(live, browser):
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    log = PageLog(context, live.base)
    try:
        page = sign_in(context, live, "operator", log)
        page.goto(f"{live.base}/operations/{live.later[1]}")
        card = page.locator("section.card", has=page.locator("#spring-setting"))
        assert card.locator("h2").first.inner_text() == "Fitted parameters"  # beside them, in their card
        s = _setting(page)
        # from the design seat: 3 steps plus the unit's unseen +1 % kO (0.42 + 0.03 steps)
        assert s["steps"] == "+3.45" and s["ci"].startswith("95 %: +") and "not known" in s["basis"] and "commissioning pair" in s["basis"]
        lo, hi = (float(x.replace("−", "-")) for x in s["ci"].removeprefix("95 %: ").split(" – "))
        assert lo < 3.0 < hi
        page.goto(f"{live.base}/operations/{live.ref[1]}")
        page.fill("#known-steps", "1")
        page.click("#commission")
        page.wait_for_selector("#is-reference")
        page.goto(f"{live.base}/operations/{live.later[0]}")  # the closing's page shows its pair too
        s = _setting(page)
        assert s["steps"] == "+3.02" and "relative to the unit's commissioning pair" in s["basis"]
        assert f"pair {live.ref[0]}/{live.ref[1]} at +1.0 steps" in s["basis"]
        assert page.locator("#setting-nearest").inner_text() == "+3"
        lo2, hi2 = (float(x.replace("−", "-")) for x in s["ci"].removeprefix("95 %: ").split(" – "))
        assert lo2 < 3.02 < hi2 and hi2 - lo2 < hi - lo
        page.locator("#spring-setting").scroll_into_view_if_needed()
        screenshot(page, "operation-spring-setting")
        # the stored pairs have no capture file: only the curve's fetch may fail
        assert [e for e in log.errors if "Failed to load resource" not in e] == [], log.errors
        assert log.foreign() == []
    finally:
        context.close()


def test_a_reader_sees_the_setting_but_no_button(live, browser):
    context = browser.new_context()
    try:
        page = sign_in(context, live, "reader")
        page.goto(f"{live.base}/operations/{live.later[1]}")
        assert page.locator("#setting-steps").count() == 1 and page.locator("#commission").count() == 0
    finally:
        context.close()
