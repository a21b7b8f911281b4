"""COMTRADE writer: read back with the ``comtrade`` package in all four data formats."""

from __future__ import annotations

import warnings
from datetime import datetime, timezone

import comtrade
import numpy as np
import pytest

from drivers.capture import Capture
from service.acquisition.capture_file import read_capture
from service.acquisition.comtrade_writer import FORMATS, write_comtrade
from drivers.synthetic import synthesize_capture


@pytest.fixture(scope="module")
def capture(breaker):
    cap, _ = synthesize_capture(breaker, "open", breaker.design_parameters(), rng=np.random.default_rng(4))
    # Clip a few vibration samples at full scale, as a real clipped shock would.
    vib = cap.vibration.copy()
    vib[100:103] = [1000.0, -1000.0, 1000.0]
    return Capture(travel=cap.travel, sample_rate=cap.sample_rate, vibration=vib,
                   start_time=datetime(2026, 3, 21, 8, 30, 15, 250000, tzinfo=timezone.utc),
                   source="test", flags=("incomplete",), first_sample_index=123456,
                   travel_limits=cap.travel_limits, vibration_limits=cap.vibration_limits,
                   meta={"window_start_s": 0.0196})


def _load(cfg):
    record = comtrade.Comtrade(use_numpy_arrays=True, use_double_precision=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the reader must find nothing to complain about
        record.load(str(cfg), str(cfg.with_suffix(".dat")))
    return record


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_within_one_quantisation_step(capture, tmp_path, fmt):
    cfg = write_comtrade(capture, tmp_path, f"rt-{fmt}", format=fmt, station="SUB-A", device="Q1")
    assert cfg == tmp_path / f"rt-{fmt}.cfg" and cfg.with_suffix(".dat").is_file()
    record = _load(cfg)
    assert record.station_name == "SUB-A" and record.rec_dev_id == "Q1"
    assert record.cfg.rev_year == "2013" and record.cfg.ft == fmt
    assert record.analog_channel_ids == ["travel", "vibration"]
    assert [ch.uu for ch in record.cfg.analog_channels] == ["rad", "g"]
    assert record.cfg.sample_rates == [[128000.0, capture.travel.size]]
    assert record.start_timestamp == datetime(2026, 3, 21, 8, 30, 15, 250000)
    assert record.trigger_timestamp == datetime(2026, 3, 21, 8, 30, 15, 269600)
    for i, original in enumerate((capture.travel, capture.vibration)):
        ch = record.cfg.analog_channels[i]
        step = ch.a if fmt != "FLOAT32" else np.abs(original) * 2**-23
        assert np.all(np.abs(np.asarray(record.analog[i]) - original) <= step + 1e-12)
    t = np.asarray(record.time)
    assert abs(t[-1] - (capture.travel.size - 1) / 128000.0) < 1e-6


@pytest.mark.parametrize("fmt", ["BINARY", "ASCII"])
def test_clipped_channel_reads_back_at_its_limits(capture, tmp_path, fmt):
    cap = read_capture(write_comtrade(capture, tmp_path, "clip", format=fmt))
    assert cap.vibration_limits == pytest.approx((-1000.0, 1000.0))
    assert cap.vibration[100] == pytest.approx(1000.0) and cap.vibration[101] == pytest.approx(-1000.0)
    assert cap.travel_limits[1] == pytest.approx(np.pi)


def test_files_appear_whole_with_no_temporaries_left(capture, tmp_path):
    out = tmp_path / "new" / "dir"
    cfg = write_comtrade(capture, out, "op", format="BINARY")
    assert sorted(p.name for p in out.iterdir()) == ["op.cfg", "op.dat", "op.hdr"]
    row = 4 + 4 + 2 * 2  # sample number, time stamp, two int16 channels
    assert cfg.with_suffix(".dat").stat().st_size == row * capture.travel.size
    assert '"incomplete"' in cfg.with_suffix(".hdr").read_text()


def test_rev_1999_and_travel_only(tmp_path):
    cap = Capture(travel=np.linspace(0.0, 1.0, 500), sample_rate=10_000.0)
    cfg = write_comtrade(cap, tmp_path, "old", rev=1999, format="ASCII")
    record = _load(cfg)
    assert record.cfg.rev_year == "1999" and record.analog_channel_ids == ["travel"]
    assert np.allclose(record.analog[0], cap.travel, atol=record.cfg.analog_channels[0].a)


@pytest.mark.parametrize("bad, message", [
    ({"format": "HEX"}, "format"), ({"rev": 2005}, "revision"), ({"name": "../x"}, "file stem")])
def test_bad_arguments_are_refused(capture, tmp_path, bad, message):
    kwargs = {"name": "ok", **bad}
    name = kwargs.pop("name")
    with pytest.raises(ValueError, match=message):
        write_comtrade(capture, tmp_path, name, **kwargs)


def test_nan_samples_are_refused(tmp_path):
    cap = Capture(travel=np.array([0.0, np.nan, 1.0]), sample_rate=1000.0)
    with pytest.raises(ValueError, match="NaN"):
        write_comtrade(cap, tmp_path, "nan")
    assert not any(tmp_path.iterdir())
