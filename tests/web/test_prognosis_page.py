"""The breaker page's prognosis fan chart and the fleet's soonest-crossing column, in a real
headless Chromium. The fits go straight into the fit table (a leak of 2 %/opening from the
26th), through the worker's drift update and prognosis hook, as in tests/service."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest

from tests.fit_rows import store_leak

from .weblive import PageLog, canvas_ink, screenshot, sign_in, start_server

VIEWPORT = {"width": 1400, "height": 1000}


@pytest.fixture(scope="module")
def live(tmp_path_factory, browser):
    app, stop = start_server(tmp_path_factory.mktemp("web-prognosis"), alarms={"baseline_n": 20})
    try:
        store_leak(app.Session, app.app.state.settings.drift_settings,
                   t0=datetime.now(timezone.utc) - timedelta(days=32), step=timedelta(days=1))
        yield app
    finally:
        stop()


def test_breaker_page_draws_the_fan_chart_and_the_fleet_lists_the_soonest_limit(live, browser):
    context = browser.new_context(viewport=VIEWPORT)
    log = PageLog(context, live.base)
    try:
        page = sign_in(context, live, "reader", log)
        fleet = page.locator("#fleet-rows tr").first.locator(".soonest-cell").inner_text()
        assert "DO in ~" in fleet and "openings" in fleet
        page.goto(f"{live.base}/breakers/1")
        page.wait_for_selector('[data-prognosis-param="DO"] canvas', timeout=30000)
        caption = page.locator('[data-prognosis-param="DO"] figcaption').inner_text()
        assert caption.startswith("DO to min_change = -0.25") and "openings (90 %:" in caption
        assert "trend since the change point" in caption
        assert canvas_ink(page, '[data-prognosis-param="DO"]') > 1000  # band, median, limit line, fits
        bo = page.locator('[data-prognosis-param="BO"] figcaption').inner_text()
        assert "no crossing within" in bo
        page.locator("#breaker-prognosis").scroll_into_view_if_needed()
        screenshot(page, "breaker-prognosis")
        assert log.errors == [], log.errors
        assert log.foreign() == []
    finally:
        context.close()
