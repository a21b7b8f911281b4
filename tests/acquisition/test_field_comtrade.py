"""Real relay and recorder COMTRADE files (../shared/realworld/comtrade): ``hvcb inspect --json``
against an independent reading of each file, the ``comtrade`` package where it reads the file,
and ``hvcb fit``'s answer (no travel channel, the channels listed)."""

from __future__ import annotations

import json
import math
import re
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest

from service.cli import main
from tests.conftest import shared_dir

FOLDERS = ["dparrini_iso8859_bin", "dparrini_sample_ascii", "dparrini_sample_bin", "dparrini_sample_float32_cff",
           "ge_c60_binary_nrates0", "pq_1999_ascii_7678hz", "ritm_binary32_2013", "ru_cp1251_binary_167ch",
           "ru_terminal_rev2000_83rates", "sel311l_1991_ascii", "sel651r_hif_1999_binary", "sepam_rev1997_binary"]
EXCEPTION_NAME = re.compile(r"\b\w*(Error|Exception)\b|Traceback|codec can't")
ANALOG_BYTES = {"BINARY": 2, "BINARY32": 4, "FLOAT32": 4}


def _folder(name: str) -> Path:
    d = shared_dir() / "realworld" / "comtrade" / name
    if not d.is_dir():
        pytest.skip(f"real-world COMTRADE folder not found at {d} (set HVCB_SHARED_DIR)")
    return d


def _capture_file(d: Path) -> Path:
    """The .cfg of the folder, else its .cff."""
    for pattern in ("*.cfg", "*.CFG", "*.cff"):
        found = sorted(d.glob(pattern))
        if found:
            return found[0]
    raise AssertionError(f"no capture in {d}")


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# -- the independent reading: plain text parsing and record counting, no project code ------------
def _independent(path: Path) -> dict:
    blob = path.read_bytes()
    if path.suffix.lower() == ".cff":
        marks = list(re.finditer(rb"--- file type: (\w+)[^\n]*---\r?\n", blob, re.IGNORECASE))
        parts = {m.group(1).upper(): blob[m.end():(marks[i + 1].start() if i + 1 < len(marks) else len(blob))]
                 for i, m in enumerate(marks)}
        cfg, dat = parts[b"CFG"], parts[b"DAT"]
        size = re.search(rb"DAT \w+: (\d+)", blob, re.IGNORECASE)
        if size:
            dat = dat[:int(size.group(1))]
    else:
        cfg = blob
        dat = next(p for p in path.parent.iterdir() if p.stem == path.stem and p.suffix.lower() == ".dat").read_bytes()
    lines = [ln.strip() for ln in cfg.decode("latin-1").replace("\x1a", "").splitlines() if ln.strip()]
    counts = [int(re.sub(r"\D", "", f)) for f in lines[1].split(",")[:3]]
    n_a, n_d = (counts[1], counts[2]) if lines[1].split(",")[1].strip().upper().endswith("A") else (counts[2], counts[1])
    k = 2 + n_a + n_d
    nrates = int(lines[k + 1])
    rates = [(float(r.split(",")[0]), int(r.split(",")[1])) for r in lines[k + 2:k + 2 + max(nrates, 1)]]
    ft = lines[k + 2 + max(nrates, 1) + 2].upper()
    stamps = None
    if ft == "ASCII":
        rows = [r for r in dat.decode("latin-1").replace("\x1a", "").splitlines() if re.search(r"\d", r)]
        samples = len(rows)
        if nrates == 0:
            stamps = [float(r.split(",")[1]) for r in rows]
    else:
        row = 8 + n_a * ANALOG_BYTES[ft] + 2 * math.ceil(n_d / 16)
        samples = len(dat) // row
        if nrates == 0:
            stamps = [struct.unpack_from("<I", dat, i * row + 4)[0] for i in range(samples)]
    if nrates == 0:
        mult_line = lines[k + 2 + max(nrates, 1) + 3]
        base = 1e-9 if len(lines[k + 2 + max(nrates, 1)].split(".")[-1]) > 6 else 1e-6
        rate = (samples - 1) / ((stamps[-1] - stamps[0]) * base * float(mult_line))
    elif len(rates) == 1:
        rate = rates[0][0]
    else:
        lasts = [n for _, n in rates]
        per = [lasts[0]] + [b - a for a, b in zip(lasts, lasts[1:])]
        rate = sum(per) / sum(c / r for c, (r, _) in zip(per, rates))
    return {"analog": n_a, "digital": n_d, "samples": samples, "rate": rate}


def _package_first_median(path: Path):
    """The first analog channel's median as the ``comtrade`` package reads it, or None where it cannot."""
    import comtrade

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rec = comtrade.load(str(path), use_numpy_arrays=True, use_double_precision=True, ignore_warnings=True)
        return float(np.nanmedian(np.asarray(rec.analog[0], float))), rec.total_samples
    except Exception:  # the package fails on several of these files: that is why the layer exists
        return None


@pytest.mark.parametrize("folder", FOLDERS)
def test_inspect_json_matches_an_independent_reading(folder, capsys):
    path = _capture_file(_folder(folder))
    code, out, err = _run(capsys, "inspect", path, "--json")
    assert code == 0, err
    r = json.loads(out)
    ref = _independent(path)
    assert len(r["analog"]) == ref["analog"]
    assert len(r["digital"]) == ref["digital"]
    assert r["samples"] == ref["samples"]
    assert r["sample_rate_hz"] == pytest.approx(ref["rate"], rel=1e-9)
    assert r["duration_s"] == pytest.approx(r["samples"] / r["sample_rate_hz"])
    for key in ("file", "revision", "file_type", "encoding", "start", "trigger", "mapping", "warnings"):
        assert key in r
    assert r["mapping"] == {"travel": None, "vibration": None}  # electrical recordings
    assert all(set(a) == {"name", "unit", "min", "median", "max"} for a in r["analog"])
    assert not EXCEPTION_NAME.search(out + err)
    pkg = _package_first_median(path)
    if pkg is not None:
        median, n_pkg = pkg
        first = r["analog"][0]
        # the package stops at the declared count; the reader also keeps one record more
        assert r["samples"] in (n_pkg, n_pkg + 1)
        assert first["median"] == pytest.approx(median, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("folder", FOLDERS)
def test_fit_says_there_is_no_travel_channel_and_lists_the_channels(folder, capsys):
    path = _capture_file(_folder(folder))
    code, out, err = _run(capsys, "fit", path, "--operation", "open")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1
    assert "no channel named 'travel'" in err and str(path) in err
    _, report, _ = _run(capsys, "inspect", path, "--json")
    first = json.loads(report)["analog"][0]["name"]
    assert f"channels: {first}" in err
    assert not EXCEPTION_NAME.search(err)


def test_table_output(capsys):
    code, out, _ = _run(capsys, "inspect", _capture_file(_folder("ru_terminal_rev2000_83rates")))
    assert code == 0
    assert "5316 at 2403.43 Hz (mean of 83 rate sections)" in out
    assert "ЗМН-1 пуск" in out and "text cp1251" in out
