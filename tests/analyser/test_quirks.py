"""Field quirks in an analyser export's header never stop the waveform: each class of quirk is
read or kept as written and flagged, through the same reader as ``hvcb inspect``/``fit`` and
uploads (tests/service/test_upload_analyser.py sends a quirky record over the API)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from drivers.analyser import parse_analyser
from drivers.capture import CaptureError
from drivers.capture_file import read_capture
from service.breaker_file import load_breaker
from service.cli import main

from .export_gen import STROKE_MM, Spec, export_text

GENERIC = "config/breakers/generic-analyser.toml"
EXAMPLE = Path(__file__).resolve().parents[2] / ".." / "shared" / "realworld" / "analyser-csv" / "example-CO-10kHz.csv"


def quirky(*replacements) -> str:
    text, _ = export_text(Spec())
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new)
    return text


def _unparsed(rec) -> dict:
    return {(u["name"], u["channel"]): u for u in rec.unparsed}


def _waveform_read(rec):
    assert rec.sample_rate == 10_000 and rec.samples == 4000
    assert np.ptp(rec.wired("travel")[0].data) > 0.9 * STROKE_MM


@pytest.mark.parametrize("spelling", ["∞", "+∞", "inf", "-Inf", "Infinity", "1.#INF", "∞ mm"])
def test_infinity_in_a_result_is_kept_as_text_and_flagged(spelling):
    text = quirky(("Open -Rebound(T1)(mm) :,1.50", f"Open -Rebound(T1)(mm) :,{spelling}"))
    rec = parse_analyser(text, source="inf.csv")
    _waveform_read(rec)
    assert rec.results["open_rebound_mm"]["T1"] == spelling
    u = _unparsed(rec)[("open_rebound_mm", "T1")]
    assert u["text"] == spelling and "infinite" in u["why"] and u["key"] == "Open - Rebound(T1)(mm)"
    assert any("kept as written" in w and spelling in w for w in rec.warnings)


@pytest.mark.parametrize("spelling", ["NaN", "nan", "-nan(ind)", "1.#QNAN", "#N/A", "#VALUE!"])
def test_nan_spellings_are_kept_as_text_and_flagged(spelling):
    text = quirky(("Contact Travel(T1)(mm) :,182.00", f"Contact Travel(T1)(mm) :,{spelling}"))
    rec = parse_analyser(text, source="nan.csv")
    _waveform_read(rec)
    assert rec.results["contact_travel_mm"]["T1"] == spelling
    assert "not a number" in _unparsed(rec)[("contact_travel_mm", "T1")]["why"]
    # the stroke falls back to the next stated value, the travel setting (182 mm)
    assert rec.stated_stroke_mm("T1") == pytest.approx(STROKE_MM)


def test_infinite_over_travel_does_not_stop_the_capture():
    """The issue's field case: 'Close - Over Travel(T1)(mm)' = ∞ refused the whole file."""
    text = quirky(("Open -Rebound(T1)(mm) :,1.50,,", "Open -Rebound(T1)(mm) :,1.50,,Close - Over Travel(T1)(mm) :,∞,,"))
    from drivers.capture_file import load_capture_bytes

    b = load_breaker(GENERIC)
    cap = load_capture_bytes(text.encode(), name="ot.csv", travel_channel=b.channels["travel"],
                             to_rad=b.travel_map.to_rad)
    assert cap.travel.min() < 0.05 and cap.travel.max() > 0.95
    assert cap.meta["analyser"]["results"]["close_over_travel_mm"]["T1"] == "∞"
    assert cap.meta["analyser"]["unparsed"][0]["name"] == "close_over_travel_mm"


@pytest.mark.parametrize("written,kv", [("765kV", 765.0), ("220 KV", 220.0), ("245 kV", 245.0), ("0.4 MV", 400.0),
                                        ("132000 V", 132.0)])
def test_numbers_with_units_inside(written, kv):
    rec = parse_analyser(quirky(("Voltage (kV) :,245", f"Voltage (kV) :,{written}")), source="u.csv")
    _waveform_read(rec)
    assert rec.metadata["rated_voltage_kv"] == pytest.approx(kv)
    assert not rec.unparsed


def test_a_unit_of_another_quantity_is_flagged_not_converted():
    rec = parse_analyser(quirky(("Contact Travel(T1)(mm) :,182.00", "Contact Travel(T1)(mm) :,182 bar"),
                                ("Sampling Speed (kC) :,10", "Sampling Speed (kC) :,10 kC")), source="u.csv")
    _waveform_read(rec)  # the rate's own unit is read: 10 kC = 10 kS/s
    u = _unparsed(rec)[("contact_travel_mm", "T1")]
    assert u["text"] == "182 bar" and "'bar', where mm is expected" in u["why"]


def test_decimal_commas_in_a_semicolon_export():
    """A European-locale export: ';' between cells, ',' as the decimal mark, in header and table."""
    plain, _ = export_text(Spec())
    text = plain.replace(",", ";").replace(".", ",")
    rec = parse_analyser(text, source="eu.csv")
    ref = parse_analyser(plain, source="plain.csv")
    _waveform_read(rec)
    assert not rec.unparsed
    assert rec.results["open_rebound_mm"]["T1"] == 1.5 and rec.metadata["linkage_ratio"] == 1.49
    np.testing.assert_array_equal(rec.wired("travel")[0].data, ref.wired("travel")[0].data)
    assert rec.results["close_velocity_m_s"] == ref.results["close_velocity_m_s"]


def test_decimal_comma_in_a_quoted_cell():
    rec = parse_analyser(quirky(("Open -Rebound(T1)(mm) :,1.50", 'Open -Rebound(T1)(mm) :,"1,75"'),
                                ("Linkage Ratio :,1.49", 'Linkage Ratio :,"1,52"')), source="q.csv")
    _waveform_read(rec)
    assert rec.results["open_rebound_mm"]["T1"] == 1.75 and rec.metadata["linkage_ratio"] == 1.52


@pytest.mark.parametrize("empty", ["", " ", "NA", "N/A", "-", "---"])
def test_empty_fields_are_none_not_flagged(empty):
    rec = parse_analyser(quirky(("Voltage (kV) :,245", f"Voltage (kV) :,{empty}"),
                                ("Contact Travel(T1)(mm) :,182.00", f"Contact Travel(T1)(mm) :,{empty}")),
                         source="e.csv")
    _waveform_read(rec)
    assert rec.metadata["rated_voltage_kv"] is None and rec.results["contact_travel_mm"]["T1"] is None
    assert not rec.unparsed
    assert rec.stated_stroke_mm("T1") == pytest.approx(STROKE_MM)  # from the travel setting


@pytest.mark.parametrize("written,iso", [
    ("01-01-2026", "2026-01-01"), ("31/01/2026", "2026-01-31"), ("31.01.26", "2026-01-31"),
    ("2026-01-31", "2026-01-31"), ("01/31/2026", "2026-01-31"), ("31-Jan-2026", "2026-01-31"),
    ("12-03-2026 14:03:22", "2026-03-12T14:03:22"), ("03/12/2026 2:03 PM", "2026-12-03T14:03:00"),
    ("2026/03/12 08:15", "2026-03-12T08:15:00")])
def test_dates_in_several_formats(written, iso):
    rec = parse_analyser(quirky(("Test Date :,01-01-2026", f"Test Date :,{written}")), source="d.csv")
    _waveform_read(rec)
    assert rec.metadata["test_date"] == iso
    assert not rec.unparsed


@pytest.mark.parametrize("written", ["32-01-2026", "sometime", "01-13-2026x"])
def test_an_unreadable_date_is_kept_and_flagged(written):
    rec = parse_analyser(quirky(("Test Date :,01-01-2026", f"Test Date :,{written}")), source="d.csv")
    _waveform_read(rec)
    if written == "01-13-2026x":  # month 13 is read day-last: 13 January
        assert rec.metadata["test_date"] == "2026-01-13"
        return
    assert rec.metadata["test_date"] == written
    assert _unparsed(rec)[("test_date", None)]["line"] == 3


def test_an_unreadable_rate_is_refused_unless_given():
    text = quirky(("Sampling Speed (kC) :,10", "Sampling Speed (kC) :,∞"))
    with pytest.raises(CaptureError, match=r"r\.csv, line 8: 'Sampling Speed \(kC\)' should be a number, got '∞' "
                                           r"\(infinite.*give the rate with --rate"):
        parse_analyser(text, source="r.csv")
    rec = parse_analyser(text, source="r.csv", rate=10_000)
    assert rec.sample_rate == 10_000 and rec.rate_source == "--rate"
    assert _unparsed(rec)[("sample_rate", None)]["text"] == "∞"


def test_velocity_line_quirk_names_its_travel_channel():
    text = quirky(("Open -Velocity (m/s) :,5.90", "Open -Velocity (m/s) :,∞"))
    rec = parse_analyser(text, source="v.csv")
    _waveform_read(rec)
    assert rec.results["open_velocity_m_s"]["T1"] == "∞"
    assert _unparsed(rec)[("open_velocity_m_s", "T1")]["key"] == "Open - Velocity (m/s)"


def test_inspect_lists_the_unparsed_fields(tmp_path, capsys):
    path = tmp_path / "quirks.csv"
    path.write_text(quirky(("Open -Rebound(T1)(mm) :,1.50", "Open -Rebound(T1)(mm) :,∞"),
                           ("Voltage (kV) :,245", "Voltage (kV) :,765kV"),
                           ("Test Date :,01-01-2026", "Test Date :,sometime")), encoding="utf-8")
    assert main(["inspect", str(path), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert {(u["name"], u["text"]) for u in r["unparsed"]} == {("open_rebound_mm", "∞"), ("test_date", "sometime")}
    assert r["metadata"]["rated_voltage_kv"] == 765.0 and r["samples"] == 4000
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "unparsed  2 header field(s) kept as written" in out
    assert "Open - Rebound(T1)(mm) = '∞' (infinite" in out and "Test Date = 'sometime'" in out


def test_shared_example_reads_every_field():
    if not EXAMPLE.is_file():
        pytest.skip(f"the shared example is absent ({EXAMPLE})")
    rec = parse_analyser(EXAMPLE.read_text(encoding="utf-8"), source=EXAMPLE.name)
    assert not rec.unparsed, rec.unparsed
    assert rec.metadata["test_date"] == "2026-01-01" and rec.metadata["rated_voltage_kv"] == 245.0
    b = load_breaker(GENERIC)
    cap = read_capture(EXAMPLE, travel_channel=b.channels["travel"], to_rad=b.travel_map.to_rad)
    assert cap.travel.size == 4000 and cap.meta["analyser"]["unparsed"] == []


def test_detect_reads_a_quirky_record_like_a_clean_one(tmp_path, capsys):
    """The issue's 7 refused files: ∞ and '765kV' in the header; hvcb detect finds both operations."""
    path = tmp_path / "field.csv"
    path.write_text(quirky(("Open -Rebound(T1)(mm) :,1.50,,", "Open -Rebound(T1)(mm) :,1.50,,Close - Over Travel(T1)(mm) :,∞,,"),
                           ("Voltage (kV) :,245", "Voltage (kV) :,765kV")), encoding="utf-8")
    assert main(["detect", str(path), "--breaker", GENERIC, "--json"]) == 0
    assert [o["operation"] for o in json.loads(capsys.readouterr().out)] == ["close", "open"]
