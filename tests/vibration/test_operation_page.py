"""The latch time over the API and on the operation page (a real headless Chromium): the latch
time and events table, the envelope drawn against the breaker's fingerprint band with its axes,
and the fingerprint's note; a capture with a dead accelerometer shows the reason instead."""

from __future__ import annotations

import dataclasses
from datetime import timedelta

import httpx
import numpy as np
import pytest

from service.prototypes.a.trip_strike import add_trip_strike
from tests.web.conftest import browser  # noqa: F401  (the browser fixture)
from tests.web.weblive import T0, PageLog, canvas_ink, sign_in, start_server, synth

LATCH_S = 1.5e-3


def _opening(breaker, seed, i, latch_s=LATCH_S, dead=False):
    cap = synth(breaker, "open", seed, None, T0 + timedelta(minutes=10 * i))
    t_motion = 0.02  # synthesize_capture's pre-trigger: motion starts at 20 ms
    vib = np.zeros_like(cap.vibration) if dead else add_trip_strike(
        cap.vibration, cap.sample_rate, t_motion, latch_s, np.random.default_rng(seed))
    return dataclasses.replace(cap, vibration=vib)


@pytest.fixture(scope="module")
def live(tmp_path_factory, breaker):
    app, stop = start_server(tmp_path_factory.mktemp("web-vibration"))
    try:
        app.ops = [app.ingest(_opening(breaker, 300 + i, i), "open") for i in range(5)]
        app.dead = app.ingest(_opening(breaker, 399, 6, dead=True), "open")
        app.wait_fits()
        yield app
    finally:
        stop()


def test_api_serves_the_latch_time_in_the_characteristics(live):
    r = httpx.get(f"{live.base}/api/v1/operations/{live.ops[-1]}", headers={"X-API-Key": live.keys["reader"]}, timeout=30)
    assert r.status_code == 200, r.text
    ch = r.json()["fit"]["characteristics"]
    assert ch["latch_time_s"] == pytest.approx(LATCH_S, abs=0.1e-3)
    assert ch["vibration_events"][0]["name"] == "first_shock"
    dead = httpx.get(f"{live.base}/api/v1/operations/{live.dead}", headers={"X-API-Key": live.keys["reader"]},
                     timeout=30).json()
    assert dead["fit"]["status"] == "done"  # a dead accelerometer never fails the fit
    assert dead["fit"]["characteristics"]["latch_time_s"] is None
    assert "flat" in dead["fit"]["characteristics"]["latch_time_reason"]


def test_operation_page_draws_the_envelope_against_the_fingerprint(live, browser):  # noqa: F811
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    log = PageLog(context, live.base)
    try:
        sign_in(context, live, "reader", log).goto(f"{live.base}/operations/{live.ops[-1]}")
        page = context.pages[-1]
        page.wait_for_selector('[data-chart="vibration-envelope"] canvas', timeout=30000)
        assert float(page.locator("#latch-time").inner_text()) == pytest.approx(LATCH_S * 1e3, abs=0.1)
        names = page.locator("#vibration-events tbody tr td:first-child").all_inner_texts()
        assert names[:2] == ["first shock", "latch release"]
        assert canvas_ink(page, '[data-chart="vibration-envelope"]') > 500
        axes = page.locator('[data-chart="vibration-envelope"]').get_attribute("data-axis-labels")
        assert axes == "time from the start of motion [ms]|envelope [g]"
        legend = page.locator('[data-chart="vibration-envelope"]').inner_text()
        assert "fingerprint mean (5 healthy operations)" in legend
        note = page.locator("#fingerprint-note").inner_text()
        assert "Fingerprint from 5 operations" in note and "latch time" in note
        page.goto(f"{live.base}/operations/{live.dead}")
        assert "flat" in page.locator("#latch-reason").inner_text()
        assert log.errors == [], log.errors
        assert log.foreign() == []
    finally:
        context.close()


def test_a_fingerprint_block_without_spread_draws_no_band_there():
    """A block seen in one healthy operation only has a level and no spread (sd None): the chart's
    band is left open there instead of failing the page (a 500 before)."""
    from types import SimpleNamespace

    from service.web.routes_vibration import vibration_view

    env = {"t0_s": -0.001, "dt_s": 0.00025, "g": [1.0, 2.0, None]}
    fp = SimpleNamespace(count_=10, operation_ids_=list(range(10)), latch_=None, events_={},
                         envelope_={"t0_s": -0.001, "dt_s": 0.00025, "mean_db": [0.0, 6.0, None],
                                    "sd_db": [1.0, None, None]},
                         shift=lambda ch: None)
    view = vibration_view({"vibration_envelope": env, "vibration_events": []}, fp)
    assert view["fingerprint"]["lo_g"][0] is not None and view["fingerprint"]["hi_g"][0] is not None
    assert view["fingerprint"]["lo_g"][1] is None and view["fingerprint"]["hi_g"][1] is None
    assert view["fingerprint"]["mean_g"][1] == 1.9953
