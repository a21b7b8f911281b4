"""The breaker page's prognosis fan chart and the fleet's soonest-crossing column, in a real
headless Chromium. The fits go straight into the fit table (a leak of 2 %/opening from the
26th), through the worker's drift update and prognosis hook, as in tests/service."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from .weblive import PageLog, canvas_ink, screenshot, sign_in, start_server

VIEWPORT = {"width": 1400, "height": 1000}


def _leak(app, n: int = 32, start: int = 25):
    from service.jobs.fit import update_drift
    from service.storage import crud

    rng = np.random.default_rng(3)
    t0 = datetime.now(timezone.utc) - timedelta(days=n)
    settings = app.app.state.settings.drift_settings
    for i in range(n):
        do = 39.5 * (1 + rng.normal(0, 0.003)) * (0.98 ** max(0, i - start))
        with app.Session() as s, s.begin():
            op, _ = crud.create_operation(s, capture_key=f"p{i}", breaker_id=1, kind="open",
                                          occurred_at=t0 + timedelta(days=i), source="replay",
                                          capture_path="/nonexistent.csv", capture_sha256="0" * 64, flags=[],
                                          sample_rate=1.0, n_samples=1)
            crud.claim_fit(s, operation_id=op.id, worker="test")
            crud.store_fit_result(s, operation_id=op.id, curve=None, result={
                "parameters": {"AO": 3424.0, "BO": 4806.0 * (1 + rng.normal(0, 0.002)), "DO": do, "EO": 3950.0},
                "ci95": {"DO": [do - 0.3, do + 0.3], "BO": [4790.0, 4822.0]}, "identifiable": True})
            update_drift(s, breaker_id=1, settings=settings)


@pytest.fixture(scope="module")
def live(tmp_path_factory, browser):
    app, stop = start_server(tmp_path_factory.mktemp("web-prognosis"), alarms={"baseline_n": 20})
    try:
        _leak(app)
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
