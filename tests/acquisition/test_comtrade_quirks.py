"""The class of problems field COMTRADE files have, built small: code pages, header files in
another code page, missing and nanosecond time stamps, rates above 30 kHz, several rate sections,
truncated data, CFF section markers, 1991 layouts and 2-digit years, and the ASCII mess (CRLF,
blank lines, trailing separators, Ctrl-Z, sample numbers from 0, one record too many)."""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest

from drivers.capture import CaptureError
from drivers.capture_file import read_capture
from drivers.comtrade import read_record
from service.cli import main

EXCEPTION_NAME = re.compile(r"\b\w*(Error|Exception)\b|Traceback|codec can't")
A_TRAVEL = 1e-4  # rad per count


def raw_signal(n: int) -> np.ndarray:
    return np.round(10000 * np.sin(np.linspace(0, 3, n))).astype(int)


def cfg_text(*, station="Station", device="Recorder", rev="1999", names=("travel", "vibration"),
             units=("rad", "g"), digital=("trip",), rates=((10000, 50),), start="01/02/2024,10:20:30.123456",
             ft="ASCII", tail=("1",)) -> str:
    lines = [f"{station},{device}" + (f",{rev}" if rev else ""),
             f"{len(names) + len(digital)},{len(names)}A,{len(digital)}D"]
    for i, (name, unit) in enumerate(zip(names, units), 1):
        lines.append(f"{i},{name},,,{unit},{A_TRAVEL},0,0,-32767,32767,1,1,P")
    for i, name in enumerate(digital, 1):
        lines.append(f"{i},{name},,,0")
    lines += ["50", str(len(rates) if rates[0][0] else 0)] + [f"{r},{n}" for r, n in rates]
    lines += [start, start, ft, *tail]
    return "\n".join(lines) + "\n"


def ascii_rows(n: int, *, step_us=100, first=1, stamps=True, n_analog=2, n_digital=1) -> list[str]:
    x = raw_signal(n)
    rows = []
    for i in range(n):
        vals = [str(first + i), str(i * step_us) if stamps else ""] + [str(x[i] // (k + 1)) for k in range(n_analog)]
        rows.append(",".join(vals + ["0"] * n_digital))
    return rows


def binary_dat(n: int, *, stamps=None, n_analog=2, n_digital=1, first=1) -> bytes:
    x = raw_signal(n)
    words = (n_digital + 15) // 16
    out = bytearray()
    for i in range(n):
        t = 0xFFFFFFFF if stamps is None else stamps[i]
        out += struct.pack(f"<II{n_analog}h{words}H", first + i, t, *[x[i] // (k + 1) for k in range(n_analog)],
                           *[0] * words)
    return bytes(out)


def write(tmp_path: Path, cfg: str | bytes, dat: str | bytes, *, name="rec", encoding="utf-8", hdr=None,
          inf=None) -> Path:
    path = tmp_path / f"{name}.cfg"
    path.write_bytes(cfg.encode(encoding) if isinstance(cfg, str) else cfg)
    (tmp_path / f"{name}.dat").write_bytes(dat.encode() if isinstance(dat, str) else dat)
    for ext, blob in (("hdr", hdr), ("inf", inf)):
        if blob is not None:
            (tmp_path / f"{name}.{ext}").write_bytes(blob)
    return path


def inspect(capsys, path, *extra) -> dict:
    code = main(["inspect", str(path), "--json", *map(str, extra)])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def refusal(capsys, path, *extra) -> str:
    code = main(["inspect", str(path), *map(str, extra)])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert not EXCEPTION_NAME.search(err), err
    return lines[0]


# -- text encodings --------------------------------------------------------------------------------
@pytest.mark.parametrize("encoding,station,names", [
    ("gbk", "变电站一号", ("行程", "振动")),
    ("cp1251", "Подстанция Южная", ("Ход", "Вибрация")),
    ("cp1251", "ПС", ("ТН", "ЗМНА")),  # upper-case abbreviations, even lengths: valid GBK bytes too
    ("gbk", "电站", ("甲相", "乙相")),
    ("iso-8859-1", "Estação Medição", ("Curso", "Vibração")),
    ("utf-8", "Umspannwerk Süd", ("Weg", "Schwingung")),
])
def test_names_in_legacy_code_pages(tmp_path, capsys, encoding, station, names):
    n = 60
    cfg = cfg_text(station=station, names=names, rates=((10000, n),))
    path = write(tmp_path, cfg, "\n".join(ascii_rows(n)) + "\n", encoding=encoding)
    r = inspect(capsys, path)
    assert r["encoding"] == encoding and r["station"] == station
    assert [a["name"] for a in r["analog"]] == list(names)
    cap = read_capture(path, travel_channel=names[0], vibration_channel=names[1])
    np.testing.assert_allclose(cap.travel, raw_signal(n) * A_TRAVEL)
    r = inspect(capsys, path, "--encoding", encoding)  # forcing the right code page changes nothing
    assert r["station"] == station


def test_a_forced_code_page_that_does_not_fit_is_refused(tmp_path, capsys):
    path = write(tmp_path, cfg_text(station="变电站"), "\n".join(ascii_rows(50)), encoding="gbk")
    line = refusal(capsys, path, "--encoding", "ascii")
    assert "rec.cfg" in line and "not valid ascii" in line
    assert "unknown text encoding" in refusal(capsys, path, "--encoding", "klingon")


def test_hdr_and_inf_in_other_code_pages_than_the_cfg(tmp_path, capsys):
    hdr, inf = "故障录波 断路器分闸\n", "Disjoncteur: déclenché à 10:20\n"
    path = write(tmp_path, cfg_text(station="Подстанция"), "\n".join(ascii_rows(50)), encoding="cp1251",
                 hdr=hdr.encode("gbk"), inf=inf.encode("iso-8859-1"))
    r = inspect(capsys, path)
    assert (r["encoding"], r["hdr_encoding"], r["inf_encoding"]) == ("cp1251", "gbk", "iso-8859-1")
    rec = read_record(path)
    assert rec.hdr_text == hdr and rec.inf_text == inf and rec.header.station == "Подстанция"


# -- time stamps and rates ---------------------------------------------------------------------------
def test_empty_time_stamp_column_with_a_rate(tmp_path, capsys):
    path = write(tmp_path, cfg_text(rates=((4000, 50),)), "\n".join(ascii_rows(50, stamps=False)))
    r = inspect(capsys, path)
    assert r["samples"] == 50 and r["sample_rate_hz"] == 4000 and r["rate_source"] == "header"


def test_no_rate_and_no_time_stamps_is_refused(tmp_path, capsys):
    path = write(tmp_path, cfg_text(rates=((0, 50),)), "\n".join(ascii_rows(50, stamps=False)))
    line = refusal(capsys, path)
    assert "rec.cfg" in line and "no sampling rate" in line and "time stamps" in line
    path = write(tmp_path, cfg_text(rates=((0, 50),), ft="BINARY"), binary_dat(50, stamps=None), name="b")
    assert "no sampling rate" in refusal(capsys, path)


def test_nanosecond_time_stamps_give_the_rate_above_30_khz(tmp_path, capsys):
    n, step_ns = 400, 20_000  # 50 kHz
    stamps = [i * step_ns for i in range(n)]
    stamps[7] = stamps[200] = 0xFFFFFFFF  # missing stamps among the others
    cfg = cfg_text(rates=((0, n),), start="01/02/2024,10:20:30.123456789", ft="BINARY")
    path = write(tmp_path, cfg, binary_dat(n, stamps=stamps))
    r = inspect(capsys, path)
    assert r["rate_source"] == "time stamps" and r["sample_rate_hz"] == pytest.approx(50_000, rel=1e-12)
    assert r["start"] == "2024-02-01T10:20:30.123456789"
    assert any("2 missing time stamp" in w for w in r["warnings"])
    rec = read_record(path)
    np.testing.assert_allclose(np.diff(rec.time), 1 / 50_000, rtol=1e-9)


@pytest.mark.parametrize("rate", [33_333.333333, 96_000, 250_000])
def test_header_rates_above_30_khz(tmp_path, capsys, rate):
    n = 5000
    path = write(tmp_path, cfg_text(rates=((rate, n),), ft="BINARY"), binary_dat(n, stamps=list(range(n))))
    r = inspect(capsys, path)
    assert r["sample_rate_hz"] == rate and r["samples"] == n
    assert r["duration_s"] == pytest.approx(n / rate)
    cap = read_capture(path)
    assert cap.sample_rate == rate and cap.t[-1] == pytest.approx((n - 1) / rate, rel=1e-12)
    np.testing.assert_allclose(cap.travel, raw_signal(n) * A_TRAVEL)


def test_several_non_integer_rate_sections(tmp_path, capsys):
    rates = ((2400.5, 100), (2399.25, 250), (2410.75, 300))
    path = write(tmp_path, cfg_text(rates=rates), "\n".join(ascii_rows(300)))
    r = inspect(capsys, path)
    counts = np.array([100, 150, 50])
    assert r["sample_rate_hz"] == pytest.approx(300 / np.sum(counts / np.array([2400.5, 2399.25, 2410.75])))
    rec = read_record(path)
    assert np.diff(rec.time)[:99] == pytest.approx(1 / 2400.5) and np.diff(rec.time)[-1] == pytest.approx(1 / 2410.75)
    cap = read_capture(path)
    assert cap.travel.size == 300 and any("resampled" in w for w in cap.meta["warnings"])


# -- layout quirks -----------------------------------------------------------------------------------
def test_the_ascii_mess_reads_the_same_values(tmp_path, capsys):
    n = 80
    clean = write(tmp_path, cfg_text(rates=((5000, n + 1),)), "\n".join(ascii_rows(n + 1)) + "\n", name="clean")
    rows = ascii_rows(n + 1, first=0)  # sample numbers from 0, one record more than declared
    messy = "\r\n\r\n".join(r.replace(",", ", ") + ", " for r in rows) + "\r\n" + "\x1a" * 5
    path = write(tmp_path, cfg_text(rates=((5000, n),)).replace("\n", "\r\n") + "\x1a\x1a", messy, name="messy")
    r = inspect(capsys, path)
    assert r["samples"] == n + 1
    text = " | ".join(r["warnings"])
    for phrase in ("blank line", "trailing separator", "Ctrl-Z", "one record more", "start at 0"):
        assert phrase in text
    np.testing.assert_array_equal(read_capture(path).travel, read_capture(clean).travel)


def test_1991_layout_with_2_digit_years(tmp_path, capsys):
    n = 40
    cfg = "\n".join(["SUB,REC", "3,2A,1D", f"1,travel,,,rad,{A_TRAVEL},0,0,-32767,32767",
                     f"2,vibration,,,g,{A_TRAVEL},0,0,-32767,32767", "1,trip,0", "60", "1", f"1000,{n}",
                     "12/31/98,23:59:59.500000", "01/02/05,00:00:00.000000", "ASCII"]) + "\n"
    path = write(tmp_path, cfg, "\n".join(ascii_rows(n, step_us=1000)))
    r = inspect(capsys, path)
    assert r["revision"] == "1991" and r["samples"] == n and [d["name"] for d in r["digital"]] == ["trip"]
    assert r["start"] == "1998-12-31T23:59:59.500000" and r["trigger"] == "2005-01-02T00:00:00.000000"
    assert sum("2-digit year" in w for w in r["warnings"]) == 2
    np.testing.assert_allclose(read_capture(path).travel, raw_signal(n) * A_TRAVEL)


def test_1991_binary_keeps_raw_minus_one_as_a_value(tmp_path, capsys):
    cfg = "\n".join(["SUB,REC", "1,1A,0D", "1,travel,,,rad,0.5,0,0,-32767,32767", "60", "1", "1000,3",
                     "12/31/98,23:59:59.500000", "12/31/98,23:59:59.500000", "BINARY"]) + "\n"
    dat = b"".join(struct.pack("<IIh", i + 1, 1000 * i, v) for i, v in enumerate((-1, 0, -1)))
    rec = read_record(write(tmp_path, cfg, dat))
    np.testing.assert_array_equal(rec.analog[0], [-0.5, 0.0, -0.5])


@pytest.mark.parametrize("cut", [3, 11])  # bytes of a 14-byte record
def test_truncated_binary_data_is_read_with_a_warning(tmp_path, capsys, cut):
    n = 100
    dat = binary_dat(n, stamps=list(range(0, 100 * n, 100)))
    size = len(dat) // n
    path = write(tmp_path, cfg_text(rates=((10000, n),), ft="BINARY"), dat[:60 * size + cut])
    r = inspect(capsys, path)
    assert r["samples"] == 60
    text = " | ".join(r["warnings"])
    assert "cut short" in text and "holds 60 of the 100 samples" in text
    np.testing.assert_allclose(read_capture(path).travel, raw_signal(n)[:60] * A_TRAVEL)


def test_data_without_a_complete_record_is_refused(tmp_path, capsys):
    path = write(tmp_path, cfg_text(rates=((10000, 100),), ft="BINARY"), binary_dat(1)[:9])
    line = refusal(capsys, path)
    assert "rec.dat" in line and "no complete record" in line and "declares 100" in line


def test_truncated_ascii_data_is_read_with_a_warning(tmp_path, capsys):
    text = "\n".join(ascii_rows(50))
    path = write(tmp_path, cfg_text(rates=((10000, 50),)), text[:text.rfind(",")])  # last line cut mid-row
    r = inspect(capsys, path)
    assert r["samples"] == 49 and any("cut short" in w for w in r["warnings"])


# -- CFF -------------------------------------------------------------------------------------------
CFF_MARKERS = [
    ("--- file type: CFG ---", "--- file type: HDR ---", "--- file type: DAT {fmt}: {size} ---"),
    ("---- FILE TYPE : CFG ----", "---- FILE TYPE : HDR ----", "---- FILE TYPE : DAT {fmt} : {size} ----"),
    ("=== file type: cfg ===", "=== file type: hdr ===", "=== file type: dat {fmt} ==="),
    ("FILE TYPE: CFG", "FILE TYPE: HDR", "FILE TYPE: DAT {fmt}: {size}"),
    ("--- CFG ---", "--- HDR ---", "--- DAT ---"),
    ("--- file type: CFG ---", "--- file type: HDR ---", "--- file type: DAT: {fmt}: {size} ---"),
    ("##### file type CFG #####", "##### file type HDR #####", "##### file type DAT {fmt} {size} bytes #####"),
]


@pytest.mark.parametrize("fmt", ["ASCII", "BINARY"])
@pytest.mark.parametrize("markers", CFF_MARKERS)
def test_cff_with_any_section_markers(tmp_path, capsys, markers, fmt):
    n = 70
    cfg = cfg_text(station="Подстанция", rates=((8000, n),), ft=fmt).encode("cp1251")
    dat = binary_dat(n, stamps=list(range(n))) if fmt == "BINARY" else ("\r\n".join(ascii_rows(n)) + "\r\n").encode()
    m_cfg, m_hdr, m_dat = (m.format(fmt=fmt, size=len(dat)).encode() for m in markers)
    blob = m_cfg + b"\r\n" + cfg + m_hdr + b"\r\n" + "说明\r\n".encode("gbk") + m_dat + b"\r\n" + dat
    (tmp_path / "rec.cff").write_bytes(blob)
    r = inspect(capsys, tmp_path / "rec.cff")
    assert r["samples"] == n and r["container"] == "CFF" and r["file_type"] == fmt
    assert r["station"] == "Подстанция" and r["hdr_encoding"] == "gbk"
    assert any("not the standard" in w for w in r["warnings"]) == (markers is not CFF_MARKERS[0])
    np.testing.assert_allclose(read_capture(tmp_path / "rec.cff").travel, raw_signal(n) * A_TRAVEL)


def test_a_file_without_cff_sections_is_refused(tmp_path, capsys):
    (tmp_path / "x.cff").write_text(cfg_text())
    line = refusal(capsys, tmp_path / "x.cff")
    assert "x.cff" in line and "not a COMTRADE CFF file" in line
    (tmp_path / "y.cff").write_text("--- file type: CFG ---\n" + cfg_text())
    assert "no DAT section" in refusal(capsys, tmp_path / "y.cff")


# -- refusals ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("case,phrase", [
    ("counts", "channel count"), ("multiplier", "multiplier of analog channel 1 'abc' is not a number"),
    ("file_type", "data file type 'EBCDIC'"), ("row_width", "line 3: 3 values where the header declares 5"),
    ("value", "line 2: the value of 'travel' 'x12' is not a number"), ("empty", "the header file is empty"),
    ("short", "the header ends before"), ("no_dat", "data file missing"),
])
def test_refusals_name_the_file_and_say_what_is_wrong(tmp_path, capsys, case, phrase):
    cfg, rows = cfg_text(), ascii_rows(50)
    if case == "counts":
        cfg = cfg.replace("3,2A,1D", "3,twoA,1D")
    elif case == "multiplier":
        cfg = cfg.replace(f"rad,{A_TRAVEL}", "rad,abc")
    elif case == "file_type":
        cfg = cfg.replace("ASCII", "EBCDIC")
    elif case == "row_width":
        rows[2] = "3,200,5"
    elif case == "value":
        rows[1] = rows[1].split(",", 2)[0] + ",100,x12,0,0"
    elif case == "empty":
        cfg = "\x1a\n"
    elif case == "short":
        cfg = "\n".join(cfg.splitlines()[:4])
    path = write(tmp_path, cfg, "\n".join(rows))
    if case == "no_dat":
        (tmp_path / "rec.dat").unlink()
    line = refusal(capsys, path)
    assert phrase in line and "rec." in line
    with pytest.raises(CaptureError) as err:  # fit, detect and diagnose read through read_capture
        read_capture(path)
    assert phrase in str(err.value)


# -- inspect: breaker mapping and CSV ----------------------------------------------------------------
def test_breaker_file_maps_channels_with_foreign_names(tmp_path, capsys):
    from tests.conftest import BREAKER_FILE

    text = BREAKER_FILE.read_text(encoding="utf-8").replace('travel = "travel"', 'travel = "Ход"')
    cam = BREAKER_FILE.with_name(re.search(r'"([^"]+\.cam\.csv)"', text).group(1))
    (tmp_path / cam.name).write_bytes(cam.read_bytes())
    (tmp_path / "b.toml").write_text(text, encoding="utf-8")
    path = write(tmp_path, cfg_text(names=("Ход", "vibration")), "\n".join(ascii_rows(50)), encoding="cp1251")
    r = inspect(capsys, path, "--breaker", tmp_path / "b.toml")
    assert r["mapping"] == {"travel": "Ход", "vibration": "vibration"} and r["mapping_source"] == "breaker file"
    assert inspect(capsys, path)["mapping"] == {"travel": None, "vibration": "vibration"}


def test_inspect_a_csv(tmp_path, capsys):
    t = np.arange(200) / 20_000
    rows = [f"{a:.8f},{np.sin(a * 100):.6f},{np.cos(a * 100):.6f}," for a in t]
    (tmp_path / "c.csv").write_bytes(("t_s,travel_rad,vibration_g\r\n" + "\r\n".join(rows) + "\r\n").encode())
    r = inspect(capsys, tmp_path / "c.csv")
    assert r["file_type"] == "CSV" and r["samples"] == 200
    assert r["sample_rate_hz"] == pytest.approx(20_000)
    assert [(a["name"], a["unit"]) for a in r["analog"]] == [("travel", "rad"), ("vibration", "g")]
    assert r["analog"][0]["max"] == pytest.approx(np.sin(t * 100).max(), abs=1e-6)
    assert r["mapping"] == {"travel": "travel", "vibration": "vibration"}
    (tmp_path / "d.csv").write_text("t_s,travel_rad\n0,0\n0.1,abc\n")
    assert "d.csv" in (line := refusal(capsys, tmp_path / "d.csv")) and "'abc' is not a number" in line


# -- damaged files: a result or a refusal in words, never anything else ------------------------------
def _damage(rng: np.random.Generator, blob: bytes) -> bytes:
    b = bytearray(blob)
    i = int(rng.integers(len(b)))
    op = int(rng.integers(4))
    if op == 0:
        del b[i:]
    elif op == 1:
        for j in rng.integers(len(b), size=int(rng.integers(1, 6))):
            b[j] = int(rng.choice(list(b",\n\r 0123456789.-aZ\x1a\xff\x00")))
    elif op == 2:
        del b[i:i + int(rng.integers(1, 40))]
    else:
        b[i:i] = rng.integers(256, size=int(rng.integers(1, 20)), dtype=np.uint8).tobytes()
    return bytes(b)


def test_damaged_files_are_read_or_refused_in_words():
    from drivers.comtrade import read_cff_bytes, read_record_bytes

    n = 40
    sources = [(cfg_text(station="Подстанция", rates=((1000, n),)).encode("cp1251"), "\n".join(ascii_rows(n)).encode()),
               (cfg_text(rates=((0, n),), ft="BINARY").encode(), binary_dat(n, stamps=list(range(0, 1000 * n, 1000)))),
               (cfg_text(names=("行程",), units=("rad",), digital=(), rates=((2000, n),), ft="ASCII").encode("gbk"),
                "\n".join(ascii_rows(n, n_analog=1, n_digital=0)).encode())]
    rng = np.random.default_rng(2026)
    outcomes = {"read": 0, "refused": 0}
    for k in range(600):
        cfg, dat = sources[k % len(sources)]
        as_cff = k % 5 == 0
        if rng.random() < 0.5:
            cfg = _damage(rng, cfg)
        else:
            dat = _damage(rng, dat)
        try:
            if as_cff:
                rec = read_cff_bytes(b"--- file type: CFG ---\n" + cfg + b"--- file type: DAT ASCII ---\n" + dat,
                                     name="f.cff")
            else:
                rec = read_record_bytes(cfg, dat, name="f.cfg", dat_name="f.dat")
        except CaptureError as exc:
            msg = str(exc)
            assert "f.cfg" in msg or "f.dat" in msg or "f.cff" in msg, msg
            assert not EXCEPTION_NAME.search(msg), msg
            outcomes["refused"] += 1
            continue
        assert rec.samples >= 1 and rec.time.shape == (rec.samples,)
        assert all(x.shape == (rec.samples,) for x in rec.analog + rec.digital)
        assert np.isfinite(rec.sample_rate) and rec.sample_rate > 0
        outcomes["read"] += 1
    assert outcomes["read"] > 100 and outcomes["refused"] > 100, outcomes
