"""Issue 56 item 7: the trip latch's time reads in words wherever a person sees it, like every
other parameter: the fleet, breaker and alarms pages (their text and their charts' axes, in a real
headless Chromium) and the condition report (every string the PDF and its figures are given).
A breaker whose latch sticks more each opening, with the shipped watched set, supplies the alarm,
the evidence charts and the prognosis where the code name used to show."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from .weblive import PageLog, sign_in, start_server
from tests.fit_rows import store_fit

CODE = "latch_time_s"
WORDS = "trip latch time"
VIEWPORT = {"width": 1400, "height": 1000}


def store_sticking_latch(Session, settings, *, t0, step, n=45, onset=30):
    """Openings with DO and BO in control and a latch time 1.2 ms that grows 0.05 ms an opening
    from ``onset``, fed through the worker's drift update (and so its prognosis hook)."""
    from service.jobs.fit import update_drift
    from service.storage import crud

    rng = np.random.default_rng(4)
    for i in range(n):
        latch = 1.2e-3 * (1 + rng.normal(0, 0.02)) + max(0, i - onset + 1) * 0.05e-3
        do, bo = 39.5 * (1 + rng.normal(0, 0.003)), 4806.0 * (1 + rng.normal(0, 0.002))
        with Session() as s, s.begin():
            store_fit(s, key=f"latch{i}", breaker_id=1, occurred_at=t0 + i * step, result={
                "parameters": {"AO": 3424.0, "BO": bo, "DO": do, "EO": 3950.0},
                "ci95": {"DO": [do - 0.3, do + 0.3], "BO": [bo - 16, bo + 16]}, "identifiable": True,
                "characteristics": {"latch_time_s": latch, "vibration_events": [
                    {"name": "first_shock", "t_s": -latch, "peak_g": 30.0, "clipped": False},
                    {"name": "latch_release", "t_s": -0.4e-3, "peak_g": 400.0, "clipped": False}]}})
            update_drift(s, breaker_id=1, settings=settings)


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    app, stop = start_server(tmp_path_factory.mktemp("web-latch"), alarms={"baseline_n": 20})
    try:
        assert CODE in app.app.state.settings.drift_settings.watched  # watched by default
        store_sticking_latch(app.Session, app.app.state.settings.drift_settings,
                             t0=datetime.now(timezone.utc) - timedelta(days=46), step=timedelta(days=1))
        yield app
    finally:
        stop()


def _seen(page) -> str:
    """What a person sees, lower-cased (a label styled in capitals reads "LATCH_TIME_S"): the page's
    text and its charts' axis labels and legends."""
    axes = page.eval_on_selector_all("[data-axis-labels]", "els => els.map(e => e.getAttribute('data-axis-labels'))")
    return (page.inner_text("body") + "\n" + "\n".join(a or "" for a in axes)).lower()


def test_the_pages_name_the_latch_in_words(live, browser):
    context = browser.new_context(viewport=VIEWPORT)
    log = PageLog(context, live.base)
    try:
        page = sign_in(context, live, "reader", log)
        fleet = _seen(page)
        assert WORDS in fleet and CODE not in fleet  # the active latch alarm, the soonest limit
        page.goto(f"{live.base}/breakers/1")
        page.wait_for_selector(f'[data-prognosis-param="{CODE}"] canvas', timeout=30000)
        breaker = _seen(page)
        assert WORDS in breaker and CODE not in breaker, [ln for ln in breaker.splitlines() if CODE in ln]
        page.goto(f"{live.base}/breakers/1/alarms")
        alarms = _seen(page) + "\n" + "\n".join(page.eval_on_selector_all(
            "svg.evidence-plot text", "els => els.map(e => e.textContent)")).lower()
        assert WORDS in alarms and CODE not in alarms, [ln for ln in alarms.splitlines() if CODE in ln]
        page.goto(f"{live.base}/alarms")
        listed = _seen(page)
        assert WORDS in listed and CODE not in listed, [ln for ln in listed.splitlines() if CODE in ln]
        assert log.errors == [], log.errors
    finally:
        context.close()


def test_the_condition_report_names_the_latch_in_words(live, monkeypatch):
    import matplotlib.text
    from fpdf import FPDF

    from service.reports.content import gather
    from service.reports.pdf import report_pdf
    from service.storage import crud

    said: list[str] = []
    for cls, name in ((FPDF, "cell"), (FPDF, "multi_cell")):
        original = getattr(cls, name)

        def spy(self, *a, _original=original, **k):
            text = k.get("text", a[2] if len(a) > 2 else "")
            said.append(str(text))
            return _original(self, *a, **k)
        monkeypatch.setattr(cls, name, spy)
    set_text = matplotlib.text.Text.set_text
    monkeypatch.setattr(matplotlib.text.Text, "set_text", lambda self, s: (said.append(str(s)), set_text(self, s))[1])
    with live.Session() as s:
        content = gather(s, breaker=crud.get_breaker(s, breaker_id=1), settings=live.app.state.settings.drift_settings)
    assert report_pdf(content)[:4] == b"%PDF"
    text = "\n".join(said)
    assert WORDS in text.lower() and CODE not in text.lower(), [t for t in said if CODE in t.lower()]
