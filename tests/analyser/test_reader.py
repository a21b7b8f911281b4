"""Every layout variation of an analyser export is read (or refused in words)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drivers.analyser import looks_like_analyser, parse_analyser
from drivers.capture import CaptureError
from drivers.capture_file import load_capture_bytes, read_capture
from service.acquisition.inspection import inspect_capture
from service.acquisition.capture_file import breaker_reading
from service.breaker_file import load_breaker
from service.cli import main

from .export_gen import STROKE_MM, Spec, export_text, write_export

GENERIC = "config/breakers/generic-analyser.toml"


@pytest.mark.parametrize("rate", [5_000, 10_000, 20_000, 40_000])
@pytest.mark.parametrize("header", [True, False])
@pytest.mark.parametrize("crlf,trailing", [(False, True), (True, False)])
def test_layouts_read_with_rate_and_channels(tmp_path, rate, header, crlf, trailing):
    path = tmp_path / "export.csv"
    write_export(path, Spec(rate=rate, header=header, crlf=crlf, trailing_comma=trailing))
    r = inspect_capture(path, rate=None if header else rate)
    assert r["samples"] == int(0.4 * rate)
    assert r["sample_rate_hz"] == rate
    assert r["rate_source"] == ("header: Sampling Speed (kC)" if header else "--rate")
    units = {a["name"]: a["unit"] for a in r["analog"]}
    assert units["T1"] == "mm" and units["C4"] == "A" and units["R1"] == "µΩ" and units["I1"] == "A"
    wired = {a["name"]: a["wired"] for a in r["analog"]}
    assert wired["T1"] and not wired["T2"] and not wired["R6"]
    assert any("not wired" in w and "T2" in w for w in r["warnings"])
    assert r["mapping"]["travel"] == "T1"
    assert (r["bare"] is True) == (not header)
    if header:
        assert r["results"]["contact_travel_mm"]["T1"] == 182.0
        assert r["results"]["open_rebound_mm"]["T1"] == 1.5
        assert r["results"]["close_velocity_m_s"]["T1"] == 4.2  # the velocity line, per channel
        assert r["metadata"]["station"] == "TEST"


def test_capture_in_rad_from_closed_and_aux_channels(tmp_path):
    path = tmp_path / "co.csv"
    write_export(path, Spec())
    b = load_breaker(GENERIC)
    cap = read_capture(path, **breaker_reading(b))
    # 0 mm (open) -> 1 rad from closed; 182 mm (closed) -> 0 rad
    assert cap.travel[:20].mean() == pytest.approx(1.0, abs=0.01)
    assert cap.travel[1500] == pytest.approx(0.0, abs=0.01)
    assert cap.meta["travel_map"]["stroke_mm"] == STROKE_MM
    assert cap.meta["travel_map"]["stroke_source"] == "stated in the record's header"
    assert {a.name for a in cap.aux_of("coil_current")} == {"C1", "C2", "C3", "C4", "C5", "C6"}
    assert "T2" not in {a.name for a in cap.aux}  # unwired channels are noted, not used


def test_bare_export_stroke_from_rest_levels(tmp_path):
    path = tmp_path / "bare.csv"
    write_export(path, Spec(header=False))
    b = load_breaker(GENERIC)
    cap = read_capture(path, **breaker_reading(b), rate=10_000)
    assert cap.meta["travel_map"]["stroke_source"] == "measured from the record's rest levels"
    assert cap.meta["travel_map"]["stroke_mm"] == pytest.approx(STROKE_MM, abs=1.0)


def test_bare_export_without_rate_refused_in_words(tmp_path):
    path = tmp_path / "bare.csv"
    write_export(path, Spec(header=False))
    with pytest.raises(CaptureError, match=r"bare\.csv: a bare analyser export .*--rate"):
        read_capture(path, **breaker_reading(load_breaker(GENERIC)))


def test_rate_contradicting_header_refused(tmp_path):
    path = tmp_path / "h.csv"
    write_export(path, Spec())
    with pytest.raises(CaptureError, match=r"states 10 kS/s .* --rate gives 20 kS/s"):
        read_capture(path, **breaker_reading(load_breaker(GENERIC)), rate=20_000)


def test_mm_travel_without_breaker_mapping_refused(tmp_path, breaker):
    path = tmp_path / "co.csv"
    write_export(path, Spec())
    with pytest.raises(CaptureError, match=r"in mm; the breaker file's \[travel\]"):
        read_capture(path, **breaker_reading(breaker))


def test_unwired_travel_channel_asked_for_is_refused(tmp_path):
    path = tmp_path / "co.csv"
    write_export(path, Spec())
    with pytest.raises(CaptureError, match="T3 is not wired"):
        read_capture(path, travel_channel="T3", to_rad=load_breaker(GENERIC).travel_map.to_rad)


def test_several_wired_travels_the_first_is_used_and_noted(tmp_path):
    path = tmp_path / "co.csv"
    write_export(path, Spec(wired_travel=(1, 2, 3)))
    cap = read_capture(path, **breaker_reading(load_breaker(GENERIC)))
    assert cap.meta["travel_channel"] == "T1"
    assert any("also wired: T2, T3" in w for w in cap.meta["warnings"])


def _malformed(tmp_path, edit):
    text, _ = export_text(Spec())
    lines = text.split("\n")
    edit(lines)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines))
    return path


def _table_line(lines):
    return next(i for i, ln in enumerate(lines) if ln.startswith("Coil Current C1"))


def test_malformed_cell_named_by_line_and_column(tmp_path):
    def edit(lines):
        i = _table_line(lines) + 10
        cells = lines[i].split(",")
        cells[7] = "12.x"
        lines[i] = ",".join(cells)
    path = _malformed(tmp_path, edit)
    line = _table_line(path.read_text().split("\n")) + 11
    with pytest.raises(CaptureError, match=rf"bad\.csv, line {line}, column 'Contact Travel T1 \(mm\)': '12\.x' is not a number"):
        read_capture(path, **breaker_reading(load_breaker(GENERIC)))


def test_short_row_named_by_line(tmp_path):
    def edit(lines):
        i = _table_line(lines) + 5
        lines[i] = lines[i][:20]
    path = _malformed(tmp_path, edit)
    line = _table_line(path.read_text().split("\n")) + 6
    with pytest.raises(CaptureError, match=rf"bad\.csv, line {line}: \d+ values, but the table's column names"):
        read_capture(path, **breaker_reading(load_breaker(GENERIC)))


def test_malformed_rate_in_header_named_by_line(tmp_path):
    def edit(lines):
        i = next(k for k, ln in enumerate(lines) if "Sampling Speed" in ln)
        lines[i] = lines[i].replace("Sampling Speed (kC) :,10", "Sampling Speed (kC) :,ten")
    path = _malformed(tmp_path, edit)
    with pytest.raises(CaptureError, match=r"bad\.csv, line 8: 'Sampling Speed \(kC\)' should be a number, got 'ten'"):
        read_capture(path, **breaker_reading(load_breaker(GENERIC)))


def test_table_without_rows_refused(tmp_path):
    def edit(lines):
        del lines[_table_line(lines) + 1:]
    path = _malformed(tmp_path, edit)
    with pytest.raises(CaptureError, match=r"bad\.csv: the table \(from line \d+\) holds 0 sample rows"):
        read_capture(path, **breaker_reading(load_breaker(GENERIC)))


def test_detected_by_content_not_name(tmp_path):
    text, _ = export_text(Spec())
    assert looks_like_analyser(text)
    path = tmp_path / "export.dump"     # an unknown suffix
    path.write_text(text)
    cap = read_capture(path, **breaker_reading(load_breaker(GENERIC)))
    assert cap.sample_rate == 10_000
    assert not looks_like_analyser("t_s,travel_rad\n0,0\n1,1\n")


def test_upload_bytes_through_the_same_reader():
    text, _ = export_text(Spec())
    cap = load_capture_bytes(text.encode(), name="co.csv", **breaker_reading(load_breaker(GENERIC)))
    assert cap.source == "upload:co.csv" and cap.meta["analyser"]["results"]["contact_travel_mm"]["T1"] == 182.0


def test_plot_length_mismatch_is_noted():
    text, _ = export_text(Spec(stated_rate=20_000))
    rec = parse_analyser(text, source="x.csv")
    assert rec.sample_rate == 20_000
    assert any("plot length is 400 ms but the table holds 4000 samples = 200 ms" in w for w in rec.warnings)


def test_inspect_cli_json_results(tmp_path, capsys):
    path = tmp_path / "co.csv"
    truth = write_export(path, Spec(rate=20_000))
    assert main(["inspect", str(path), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["samples"] == 8000 and r["sample_rate_hz"] == 20_000
    assert r["results"]["coil_current_peak_a"] == {c: truth["coil_peak_a"][c] for c in ("C1", "C4")}
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "8000 at 20000 Hz" in out and "T2 (not wired)" in out and "contact_travel_mm: T1 182" in out


def test_inspect_bare_cli_with_rate(tmp_path, capsys):
    path = tmp_path / "bare.csv"
    write_export(path, Spec(header=False, rate=5_000))
    assert main(["inspect", str(path), "--rate", "5k", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["sample_rate_hz"] == 5_000 and r["samples"] == 2000 and r["duration_s"] == pytest.approx(0.4)


def test_travel_table_and_zero_closed(tmp_path):
    """A non-linear linkage given as a table, and a record whose 0 mm is the closed position."""
    (tmp_path / "link.csv").write_text("contact_mm,shaft_rad\n0,0\n100,0.4\n182,1.0\n")
    src = open(GENERIC).read().replace('mm_per_rad = "record"', 'table = "link.csv"')
    (tmp_path / "b.toml").write_text(src)
    b = load_breaker(tmp_path / "b.toml")
    rad, info = b.travel_map.to_rad(np.array([0.0, 100.0, 182.0, 191.1]), "mm", None)
    assert rad[:3] == pytest.approx([1.0, 0.6, 0.0])
    assert rad[3] == pytest.approx(-9.1 * 0.6 / 82)  # past the table: the last segment's slope
    src2 = open(GENERIC).read().replace('mm_per_rad = "record"', "mm_per_rad = 182.0").replace(
        'record_zero = "open"', 'record_zero = "closed"')
    (tmp_path / "c.toml").write_text(src2)
    rad2, _ = load_breaker(tmp_path / "c.toml").travel_map.to_rad(np.array([0.0, 91.0]), "mm", None)
    assert rad2 == pytest.approx([0.0, 0.5])


def test_bad_travel_section_refused(tmp_path):
    src = open(GENERIC).read().replace('mm_per_rad = "record"', "mm_per_rad = -3")
    (tmp_path / "b.toml").write_text(src)
    from service.breaker_file import BreakerFileError

    with pytest.raises(BreakerFileError, match=r"\[travel\] mm_per_rad must be a positive number"):
        load_breaker(tmp_path / "b.toml")


def test_column_and_key_spacing_variants_are_read():
    """Exports differ in spacing: 'Contact Travel T1(mm)', 'Sampling Speed(kC)', an extra column."""
    text, _ = export_text(Spec())
    text = text.replace("Contact Travel T", "Contact Travel  T").replace(" (mm),", "(mm),").replace(
        "Sampling Speed (kC)", "Sampling Speed(kC)").replace("DCRM Current CH6 in Amp,", "DCRM Current CH6 in Amp,Aux A1,")
    rec = parse_analyser(text, source="v.csv")
    assert rec.sample_rate == 10_000 and rec.samples == 4000
    assert [c.name for c in rec.wired("travel")] == ["T1"]
    assert any("'Aux A1'" in w for w in rec.warnings)  # an unknown column is named, not guessed
