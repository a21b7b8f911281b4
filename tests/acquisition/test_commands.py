"""``hvcb detect`` and ``hvcb capture`` through the real CLI entry point."""

from __future__ import annotations

import json

import numpy as np
import pytest

from service import cli
from drivers.stream_script import ScriptedOperation, ScriptedStream

from .conftest import BREAKER_FILE


@pytest.fixture
def hvcb(capsys):
    """Run ``hvcb`` in-process; returns (exit code, stdout, stderr)."""

    def run(*argv):
        code = cli.main([str(a) for a in argv])
        out, err = capsys.readouterr()
        return code, out, err

    return run


@pytest.mark.parametrize("name", ["open-nominal", "open-nominal-ascii", "open-buffer-leak", "close-nominal"])
def test_detect_shared_samples(hvcb, samples_dir, name):
    truth = json.loads((samples_dir / f"{name}.truth.json").read_text())
    code, out, err = hvcb("detect", samples_dir / f"{name}.cfg", "--breaker", BREAKER_FILE, "--json")
    assert code == 0, err
    rows = json.loads(out)
    assert len(rows) == 1
    row = rows[0]
    assert row["operation"] == truth["kind"] and row["flags"] == []
    # The window starts at the latch shock, about 0.4 ms before motion.
    assert abs(row["t_start_s"] - (truth["t_motion_start"] - 0.4e-3)) < 0.1e-3
    assert abs(row["t_start_s"] - truth["t_motion_start"]) < 0.5e-3
    limit = 1e-3 if truth["kind"] == "open" else 3e-3
    assert abs(row["t_end_s"] - truth["t_max"]) < limit


def test_detect_csv_stream_lists_operations_in_time_order(hvcb, breaker, tmp_path):
    ops = [ScriptedOperation("open", 0.1), ScriptedOperation("close", 0.35)]
    stream = ScriptedStream(breaker, duration_s=0.5, seed=12, operations=ops)
    travel, vib = stream.samples(0, stream.n_samples)
    t = np.arange(travel.size) / stream.fs
    path = tmp_path / "stream.csv"
    np.savetxt(path, np.column_stack([t, travel, vib]), delimiter=",", fmt="%.9g",
               header="t_s,travel_rad,vibration_g", comments="")
    code, out, err = hvcb("detect", path, "--breaker", BREAKER_FILE, "--json")
    assert code == 0, err
    rows = json.loads(out)
    assert [r["operation"] for r in rows] == ["open", "close"]
    for r, truth in zip(rows, stream.truth):
        assert abs(r["t_start_s"] - truth.t_shock_s) < 0.5e-3
    code, out, _ = hvcb("detect", path, "--breaker", BREAKER_FILE)
    assert code == 0 and "open" in out and "close" in out


def _one_line_error(code, out, err):
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hvcb detect: error:")
    return lines[0]


def test_detect_missing_file(hvcb, tmp_path):
    line = _one_line_error(*hvcb("detect", tmp_path / "none.cfg", "--breaker", BREAKER_FILE, "--json"))
    assert "not found" in line


def test_detect_malformed_comtrade(hvcb, tmp_path):
    (tmp_path / "bad.cfg").write_text("STATION,DEV,2013\nthis is not a channel count\n")
    (tmp_path / "bad.dat").write_bytes(b"\x00\x01")
    line = _one_line_error(*hvcb("detect", tmp_path / "bad.cfg", "--breaker", BREAKER_FILE))
    assert "malformed COMTRADE" in line


def test_detect_nan_samples(hvcb, tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("t_s,travel_rad,vibration_g\n0.0,0.0,0.1\n0.001,nan,0.2\n0.002,0.0,0.1\n")
    line = _one_line_error(*hvcb("detect", path, "--breaker", BREAKER_FILE, "--json"))
    assert "NaN" in line


def test_detect_missing_breaker_file(hvcb, samples_dir, tmp_path):
    line = _one_line_error(*hvcb("detect", samples_dir / "open-nominal.cfg", "--breaker", tmp_path / "x.toml"))
    assert "breaker file not found" in line


def test_capture_replay_writes_comtrade(hvcb, samples_dir, tmp_path):
    out_dir = tmp_path / "captures"
    code, out, err = hvcb("capture", "--driver", "replay", "--file", samples_dir / "open-nominal.cfg",
                          "--file", samples_dir / "close-nominal.cfg", "--out", out_dir,
                          "--breaker", BREAKER_FILE, "--json")
    assert code == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    assert [r["operation"] for r in lines] == ["open", "close"]
    assert sorted(p.suffix for p in out_dir.iterdir()) == [".cfg", ".cfg", ".dat", ".dat", ".hdr", ".hdr"]
    assert "2 captures" in err


def test_capture_needs_driver_options(hvcb, tmp_path):
    code, _, err = hvcb("capture", "--driver", "replay", "--out", tmp_path, "--breaker", BREAKER_FILE)
    assert code == 2 and "--file" in err
    code, _, err = hvcb("capture", "--driver", "serial", "--out", tmp_path, "--breaker", BREAKER_FILE)
    assert code == 2 and "--url" in err
