"""The analyser-style pass/fail of the condition report, and the breaker file's
[characteristic_limits] table it reads."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.breaker_file import BreakerFileError, parse_breaker_text
from service.breaker_limits import CharacteristicLimit, ParameterLimit
from service.mechanics.nomenclature import UNITS
from service.reports.verdicts import (FAIL, NO_BASELINE, NO_LIMIT, NOT_MEASURED, PASS, characteristic_verdicts,
                                      overall, parameter_verdicts)

REFERENCE = Path(__file__).resolve().parents[2] / "config" / "breakers" / "reference-252kV.toml"


def test_characteristics_are_judged_in_display_units_against_their_range():
    limits = {"operating_time_s": CharacteristicLimit(min=0.0101, max=0.0123),
              "average_speed_rad_s": CharacteristicLimit(min=29.4)}
    rows = {v.name: v for v in characteristic_verdicts(
        {"operating_time_s": 0.0130, "average_speed_rad_s": 32.6, "overtravel_rad": 0.025}, limits)}
    t = rows["operating_time_s"]
    assert (t.unit, round(t.value, 6), t.low, t.high, t.result) == ("ms", 13.0, pytest.approx(10.1),
                                                                    pytest.approx(12.3), FAIL)
    assert t.limit_text == "10.1 to 12.3"
    assert rows["average_speed_rad_s"].result == PASS and rows["average_speed_rad_s"].limit_text == "≥ 29.4"
    assert rows["overtravel_rad"].result == NO_LIMIT and rows["overtravel_rad"].value == pytest.approx(25.0)
    assert rows["rebound_rad"].value is None and rows["rebound_rad"].result == NO_LIMIT
    # a limited characteristic the fit could not read (NaN) is "not measured", never a pass
    nan = characteristic_verdicts({"operating_time_s": float("nan")}, limits)
    assert nan[0].result == NOT_MEASURED


def test_a_relative_parameter_limit_needs_the_baseline():
    limits = {"DO": ParameterLimit(min_change=-0.25), "BO": ParameterLimit(min_change=-0.1, max_change=0.1),
              "EO": ParameterLimit(max=4000.0)}
    rows = {v.name: v for v in parameter_verdicts({"AO": 3400.0, "BO": 5400.0, "DO": 31.0, "EO": 3950.0},
                                                  ("AO", "BO", "DO", "EO"), limits, {"DO": 40.0, "BO": 4800.0},
                                                  UNITS)}
    assert rows["DO"].low == pytest.approx(30.0) and rows["DO"].result == PASS
    assert (rows["BO"].low, rows["BO"].high) == (pytest.approx(4320.0), pytest.approx(5280.0))
    assert rows["BO"].result == FAIL
    assert rows["EO"].result == PASS and rows["EO"].unit == "s⁻²"
    assert rows["AO"].result == NO_LIMIT
    no_base = parameter_verdicts({"DO": 31.0}, ("DO",), limits, {}, UNITS)[0]
    assert no_base.result == NO_BASELINE and no_base.low is None
    assert overall(rows.values()) == FAIL
    assert overall([rows["DO"], rows["AO"]]) == PASS
    assert overall([rows["AO"]]) == NO_LIMIT


def test_the_reference_breaker_file_gives_characteristic_limits():
    model = parse_breaker_text(REFERENCE.read_text(), source=str(REFERENCE))
    assert model.characteristic_limits.open["operating_time_s"].max == pytest.approx(0.0123)
    assert set(model.characteristic_limits.close) == {"operating_time_s", "average_speed_rad_s"}


@pytest.mark.parametrize("table, words", [
    ('[characteristic_limits.open]\nopening_time = { max = 0.03 }', "unknown characteristic 'opening_time'"),
    ('[characteristic_limits.open]\noperating_time_s = { min = 0.02, max = 0.01 }', "must be below max"),
    ('[characteristic_limits.open]\noperating_time_s = 0.02', "must be a table"),
    ('[characteristic_limits.shut]\noperating_time_s = { max = 0.03 }', "shut"),
])
def test_a_bad_characteristic_limit_is_refused_in_words(table, words):
    text = REFERENCE.read_text().split("[characteristic_limits.open]")[0] + table + "\n"
    with pytest.raises(BreakerFileError) as exc:
        parse_breaker_text(text, source="bay1.toml")
    assert "bay1.toml" in str(exc.value) and "[characteristic_limits]" in str(exc.value)
    assert words in str(exc.value)
