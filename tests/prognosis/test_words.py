"""The prognosis in words (service.prognosis.words): names, units, limits as values and as
changes from the baseline, whole openings, dates, "no trend"."""

from __future__ import annotations

from service.prognosis import words


def base(**kw):
    p = {"parameter": "DO", "limit": 31.8, "direction": "falling", "limit_text": "min_change = -0.25",
         "baseline": 42.4, "current": 23.96, "limits": [{"direction": "falling", "value": 31.8}],
         "status": "crossed", "reason": "", "operations_to_limit": {"p05": 0.0, "median": 0.0, "p95": 0.0},
         "date_to_limit": None, "horizon_years": 10.0, "horizon_operations": 3652.5, "basis": "change point",
         "basis_operations": 40}
    p.update(kw)
    return p


def test_a_crossed_limit_reads_as_the_issue_asks():
    assert words.summary(base()) == ("Buffer damping (DO) crossed its limit: trend level 24.0 s⁻¹; limit 31.8 s⁻¹, 25 % below "
                                     "its baseline of 42.4 s⁻¹. Service the buffer (oil level and seals).")
    assert words.fleet_text(base()) == "buffer damping (DO): limit crossed, service due"


def test_a_crossing_ahead_has_whole_openings_dates_and_both_limits():
    p = base(parameter="BO", status="ok", current=4500.0, baseline=4806.0, limit=4325.4,
             limits=[{"direction": "falling", "value": 4325.4}, {"direction": "rising", "value": 5286.6}],
             operations_to_limit={"p05": 120.4, "median": 250.6, "p95": 612.2},
             date_to_limit={"p05": "2027-01-01T00:00:00+00:00", "median": "2027-05-10T12:00:00+00:00",
                            "p95": "2028-09-01T00:00:00+00:00"})
    text = words.summary(p)
    assert text.startswith("Opening spring force (BO) reaches its limit in about 251 openings, around 2027-05-10 "
                           "(90 %: 2027-01-01 – 2028-09-01); 90 % interval 120–612 openings."), text
    assert "limits 4,325 s⁻² and 5,287 s⁻², 10 % below and 10 % above its baseline of 4,806 s⁻²" in text
    assert words.fleet_text(p) == "opening spring force (BO): limit in about 251 openings (around 2027-05-10)"


def test_no_trend_is_not_a_due_date():
    p = base(status="no trend", current=42.3, operations_to_limit={"p05": 1318.7, "median": None, "p95": None},
             date_to_limit={"p05": "2030-03-01T00:00:00+00:00", "median": None, "p95": None})
    text = words.summary(p)
    assert text.startswith("Buffer damping (DO): no trend. Trend level 42.3 s⁻¹; limit 31.8 s⁻¹")
    assert "not expected to reach its limit within 10 years at this rate" in text
    assert "At the earliest (5 %): in 1,319 openings, 2030-03-01." in text
    assert words.fleet_text(p) == "buffer damping (DO): no trend, not within 10 years"


def test_values_have_three_significant_figures_and_a_minus_sign():
    assert words.value(23.96, "DO") == "24.0 s⁻¹" and words.value(4806.2, "BO") == "4,806 s⁻²"
    assert words.value(-0.01234, "DO") == "−0.0123 s⁻¹" and words.value(0.5, "BC") == "0.500"
    assert words.operations(1.2, "DO") == "1 opening" and words.operations(2.0, "CC") == "2 closings"


def test_a_median_beyond_the_horizon_keeps_the_earliest_crossing():
    p = base(status="ok", current=40.1, operations_to_limit={"p05": 2900, "median": None, "p95": None},
             date_to_limit={"p05": "2033-06-01T00:00:00+00:00", "median": None, "p95": None})
    text = words.summary(p)
    assert text.startswith("Buffer damping (DO): not expected to reach its limit within 10 years at this rate.")
    assert text.endswith("At the earliest (5 %): in 2,900 openings, 2033-06-01."), text
    assert words.fleet_text(p) == "buffer damping (DO): not within 10 years"


def test_the_latch_is_counted_in_openings_as_it_is_read_from_them():
    from service.prognosis import words

    assert words.operations(12, "latch_time_s") == "12 openings"
    assert words.operations(1, "buffer_ratio") == "1 opening"
    assert words.operations(3, "AC") == "3 closings"
