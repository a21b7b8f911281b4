"""The [limits] table of the breaker file: accepted forms and bad limits refused in words."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.breaker_file import BreakerFileError, load_breaker, parse_breaker_text

REFERENCE = Path(__file__).resolve().parents[2] / "config" / "breakers" / "reference-252kV.toml"
TEXT = REFERENCE.read_text()
WITHOUT = (TEXT.split("[limits]")[0] + "\n" + TEXT.split("[limits]")[1].split("\n\n", 1)[1]).replace(
    "latch_time_max_ms = 2.3", "")  # the latch's limit ([vibration]) is a limit too


def limits_of(table: str):
    return parse_breaker_text(WITHOUT + "\n[limits]\n" + table, source="site.toml").limits


def test_reference_breaker_has_limits_and_loads():
    limits = parse_breaker_text(TEXT, source=str(REFERENCE)).limits
    assert dict(limits.items())["DO"].bounds(40.0) == [("falling", pytest.approx(30.0))]
    assert dict(limits.items())["BO"].bounds(5000.0) == [("falling", pytest.approx(4500.0)),
                                                          ("rising", pytest.approx(5500.0))]
    load_breaker(REFERENCE)  # the whole file still builds a breaker


def test_absolute_and_relative_forms():
    limits = dict(limits_of('DO = { min = 30.0 }\nEO = { max = 6500.0 }\nAO = { max_change = 0.2 }').items())
    assert limits["DO"].bounds(39.5) == [("falling", 30.0)]
    assert limits["EO"].bounds(1.0) == [("rising", 6500.0)]
    assert limits["AO"].bounds(3000.0) == [("rising", pytest.approx(3600.0))]
    assert limits["DO"].describe() == "min = 30"


def test_no_limits_table_means_no_limits():
    assert not parse_breaker_text(WITHOUT, source="x.toml").limits


@pytest.mark.parametrize("table, words", [
    ("DO = { min = -3.0 }", "[limits] DO.min: Input should be greater than 0"),
    ("XX = { min = 3.0 }", "unknown parameter 'XX'"),
    ("DO = { min = 30.0, min_change = -0.2 }", "[limits] DO: give min or min_change, not both"),
    ("BO = { max = 5000.0, max_change = 0.1 }", "[limits] BO: give max or max_change, not both"),
    ("DO = { }", "[limits] DO: needs a bound"),
    ("DO = { minimum = 30.0 }", "[limits] DO.minimum: is not a known key"),
    ("DO = 30.0", "[limits] DO: must be a table such as { min = 30.0 }"),
    ("DO = { min_change = 0.2 }", "[limits] DO.min_change: Input should be less than 0"),
    ("DO = { min_change = -1.5 }", "[limits] DO.min_change: Input should be greater than -1"),
    ("BO = { min = 6000.0, max = 5000.0 }", "[limits] BO: min 6000 must be below max 5000"),
    ("DO = { min = nan }", "[limits] DO.min"),
])
def test_bad_limit_is_refused_naming_file_and_key(table, words):
    with pytest.raises(BreakerFileError) as err:
        limits_of(table)
    assert "site.toml" in str(err.value) and words in str(err.value)
