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
        assert fleet.startswith("buffer damping (DO): limit in about ") and "openings" in fleet, fleet
        page.goto(f"{live.base}/breakers/1")
        page.wait_for_selector('[data-prognosis-param="DO"] canvas', timeout=30000)
        caption = page.locator('[data-prognosis-param="DO"] figcaption').inner_text()
        assert caption.startswith("Buffer damping (DO) reaches its limit in about "), caption
        assert "openings" in caption and "90 % interval" in caption and "25 % below its baseline of" in caption
        assert "Trend since the change point" in caption
        assert canvas_ink(page, '[data-prognosis-param="DO"]') > 1000  # band, median, limit line, fits
        bo = page.locator('[data-prognosis-param="BO"] figcaption').inner_text()
        assert "no trend" in bo and "not expected to reach its limit within" in bo, bo
        # both limits of BO's two-sided limit are drawn, and the legend never reads "--"
        page.wait_for_selector('[data-prognosis-param="BO"] canvas', timeout=30000)
        legend = page.locator('[data-prognosis-param="BO"] .u-legend').inner_text()
        assert "lower limit" in legend and "upper limit" in legend and "s⁻²" in legend, legend
        legends = " ".join(page.locator("#prognosis-charts .u-legend").all_inner_texts())
        assert "--" not in legends, legends
        page.locator("#breaker-prognosis").scroll_into_view_if_needed()
        screenshot(page, "breaker-prognosis")
        assert log.errors == [], log.errors
        assert log.foreign() == []
    finally:
        context.close()
