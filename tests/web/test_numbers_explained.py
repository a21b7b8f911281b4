"""Every number on the pages carries its unit (issue 30): the alarms, breaker and operation pages
of the demo's history, in a real Chromium.

The history is the demo's own script (service/api/demo.py: the virtual prototype with mild
effects, healthy openings, then a buffer oil leak), shortened so that it fits in a test; its
captures are ingested directly instead of through the Modbus emulator.
"""

from __future__ import annotations

import re
from contextlib import contextmanager
from datetime import timedelta

import pytest

from .weblive import T0, PageLog, sign_in, start_server

VIEWPORT = {"width": 1400, "height": 900}
# The units the pages use (service/mechanics/nomenclature.py, the travel characteristics, the
# drift statistic in baseline standard deviations σ, counts of fits and samples).
UNIT = re.compile(r"(s⁻²|s⁻¹|σ|mrad|rad/s|rad|ms|mm|m/s|kHz|Hz|%|°C|\bK\b|\bfits?\b|\bsamples\b|\bg\b)")
NUMBER = re.compile(r"[−+-]?\d+(?:[.,]\d+)?")
# Not measurements: times, operation and alarm numbers, a count with its own noun.
NOT_A_QUANTITY = [re.compile(p) for p in (r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d UTC", r"#\d+", r"operation #?\d+",
                                          r"n = \d+", r"\d+ stored", r"page \d+ of \d+", r"reference-252kV",
                                          r"last \d+ (?:good )?fits", r"\b\d+ (?:reconnects|retries|restarts|frames|"
                                          r"captures|abandoned|CRC|dropped)")]
# Labels whose value is a count, a name or a state, never a quantity with a unit.
COUNT_LABELS = {"operations", "daq link", "source", "fit", "status", "identifiable", "baseline since",
                "last opening", "last closing", "direction"}


def quantities(text: str) -> list[str]:
    for pattern in NOT_A_QUANTITY:
        text = pattern.sub(" ", text)
    return NUMBER.findall(text)


@pytest.fixture(scope="module")
def demo(tmp_path_factory, breaker, browser):
    from service.api.demo import DemoScript, history

    script = DemoScript(healthy_ops=8, total_ops=22, leak_per_op=0.02)
    app, stop = start_server(tmp_path_factory.mktemp("web-numbers"), name="engineer",
                             alarms={"baseline_n": 6})
    try:
        for n, (i, kind, cap) in enumerate(history(breaker, script)):
            at = T0 + timedelta(minutes=10 * n)
            app.ingest(type(cap)(**{**cap.__dict__, "start_time": at}), kind)
        app.wait_fits(timeout=600)
        yield app
    finally:
        stop()


def kv_cells(page, scope: str = "body") -> list[tuple[str, str]]:
    return page.eval_on_selector_all(f"{scope} .kv", """els => els.map(e => [
        (e.querySelector('.k') || {innerText: ''}).innerText.trim(),
        (e.querySelector('.v') || {innerText: ''}).innerText.trim()])""")


def assert_units(cells, where: str) -> None:
    missing = [f"{k}: {v!r}" for k, v in cells
               if k.lower() not in COUNT_LABELS and quantities(v) and not UNIT.search(v)]
    assert not missing, f"numbers without a unit on the {where}:\n" + "\n".join(missing)


def signed(text: str) -> float:
    return float(text.replace("−", "-"))


@contextmanager
def reader_page(browser, demo, path: str, ready: bool = True):
    """A reader's page at ``path`` in a fresh browser context; no console error by the end."""
    context = browser.new_context(viewport=VIEWPORT)
    log = PageLog(context, demo.base)
    try:
        page = sign_in(context, demo, "reader", log)
        page.goto(demo.base + path)
        if ready:
            page.wait_for_selector('body[data-ready="1"]', timeout=60000)
        yield page
        assert log.errors == [], log.errors
    finally:
        context.close()


def test_alarms_page_values_have_units_and_the_now_value_follows_the_latest_fit(demo, browser):
    from service.storage import crud

    with reader_page(browser, demo, "/alarms", ready=False) as page:
        card = page.locator('section.alarm[data-parameter="DO"]').first
        assert card.count() == 1, page.locator("#alarm-list").inner_text()
        assert_units(kv_cells(page, "#alarm-list"), "alarms page")
        text = page.locator("#alarm-list").inner_text()
        assert "−0.0 %" not in text and "-0.0 %" not in text
        # thresholds: 3 significant figures, never more than 4
        thresholds = re.findall(r"(?:warning|alarm) ([−\d.]+) σ", text)
        assert thresholds, text
        for t in thresholds:
            assert len(t.replace("−", "").replace(".", "").lstrip("0")) <= 4, t
        # the line states the value now and when raised, each with its unit and change
        line = card.locator("p.message").inner_text()
        assert re.search(r"now [\d.]+ s⁻¹ \([−+][\d.]+ % from baseline\)", line), line
        assert re.search(r"when raised [\d.]+ s⁻¹ \([−+][\d.]+ %\)", line), line
        # "now" is the latest fit's DO, which has fallen well past the value when raised
        with demo.Session() as s:
            latest = crud.latest_fit(s, breaker_id=1, kind="open")
        shown_now = signed(card.locator('[data-value="now"] .num').first.inner_text().split()[0])
        shown_raised = signed(card.locator('[data-value="raised"] .num').first.inner_text().split()[0])
        assert shown_now == pytest.approx(latest.parameters["DO"], rel=1e-3)
        assert shown_now < shown_raised * 0.9, (shown_now, shown_raised)


def test_breaker_page_alarm_line_and_summary_have_units(demo, browser):
    with reader_page(browser, demo, "/breakers/1") as page:
        assert_units(kv_cells(page), "breaker page")
        lines = page.locator("#breaker-alarms .alarm-line").all_inner_texts()
        assert lines, page.locator("#breaker-alarms").inner_text()
        for line in lines:
            for number in quantities(line):
                assert re.search(re.escape(number) + r" ?(s⁻²|s⁻¹|%|–)", line), (number, line)
        # the operations table's numeric column names its unit in the header
        assert "mrad" in page.locator("#operations thead").inner_text().lower()
        # the drift charts' legends give the thresholds in σ to 3 significant figures
        page.wait_for_selector("[data-drift] .u-legend")
        legends = " ".join(page.locator("[data-drift] .u-legend").all_inner_texts())
        thresholds = re.findall(r"(?:warning|alarm) ([\d.]+)", legends)
        assert thresholds and all(len(t.replace(".", "").lstrip("0")) <= 4 for t in thresholds), legends
        assert "σ" in legends, legends


def test_operation_page_rows_have_units(demo, browser):
    from sqlalchemy import select

    from service.storage.models import OperationRow

    with demo.Session() as s:
        op_id = s.scalar(select(OperationRow.id).where(OperationRow.kind == "open").order_by(OperationRow.id.desc()).limit(1))
    with reader_page(browser, demo, f"/operations/{op_id}") as page:
        assert_units(kv_cells(page, "#op-summary"), "operation page")
        rows = page.eval_on_selector_all("#op-tables table.params tbody tr",
                                         "rs => rs.map(r => [...r.cells].map(c => c.innerText.trim()))")
        assert rows
        for cells in rows:
            if any(quantities(c) for c in cells[1:]):
                assert cells[-1] and not NUMBER.fullmatch(cells[-1]), f"no unit in the last column: {cells}"


PROGNOSIS_UNIT = re.compile(r"\s?(?:s⁻²|s⁻¹|ms|%|openings?|closings?|years|fits)")  # ms: the latch time
DATE = re.compile(r"\b\d{4}-\d\d-\d\d\b")


def prognosis_numbers_without_unit(text: str) -> list[str]:
    """Numbers in a prognosis text not followed by a unit (a range's first end takes the unit
    of its second: "5–7 openings"); dates are not quantities."""
    text = DATE.sub(" ", text)
    missing = []
    for m in re.finditer(r"[−+-]?\d[\d,]*(?:\.\d+)?", text):
        rest = text[m.end():]
        rest = re.sub(r"^\s?–\s?[\d,]+(?:\.\d+)?", "", rest)
        if not PROGNOSIS_UNIT.match(rest):
            missing.append(f"{m.group()!r} in {text!r}")
    return missing


def test_prognosis_card_and_fleet_say_it_in_words_with_units(demo, browser):
    """Issue 37: the demo's BO is flat, and its card says "no trend" (not a due date); every
    number of the prognosis card and the fleet's column has its unit; openings are whole."""
    with reader_page(browser, demo, "/breakers/1") as page:
        page.wait_for_selector('[data-prognosis-param="BO"] figcaption', timeout=60000)
        captions = dict(page.eval_on_selector_all("#prognosis-charts figure", """fs => fs.map(f =>
            [f.getAttribute('data-prognosis-param'), f.querySelector('figcaption').innerText.trim()])"""))
        bo = captions["BO"]
        assert bo.startswith("Opening spring force (BO): no trend."), bo
        assert "not expected to reach its limit within" in bo and "% below and" in bo and "% above its baseline" in bo
        do = captions["DO"]
        assert do.startswith("Buffer damping (DO)"), do
        missing = [x for text in captions.values() for x in prognosis_numbers_without_unit(text)]
        assert not missing, "prognosis numbers without a unit:\n" + "\n".join(missing)
        for text in captions.values():
            assert not re.search(r"\d\.\d+ openings", text), text  # whole openings
            assert "min_change" not in text and "max_change" not in text, text
        legends = " ".join(page.locator("#prognosis-charts .u-legend").all_inner_texts())
        assert legends and "--" not in legends, legends
    with reader_page(browser, demo, "/", ready=False) as page:
        cell = page.locator("#fleet-rows tr").first.locator(".soonest-cell").inner_text().strip()
        assert cell.startswith(("buffer damping (DO)", "opening spring force (BO)")), cell
        assert not prognosis_numbers_without_unit(cell), cell
