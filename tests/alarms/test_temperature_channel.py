"""The breaker file's [channels] temperature: a COMTRADE analog channel read with the capture."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.capture_file import load_comtrade_bytes


def _record(temp_values, unit="C", name="mech_temp") -> tuple[bytes, bytes]:
    n = 64
    travel = np.linspace(0.0, 1.0, n)
    cfg = "\n".join([
        "hvcb-test,rec,1999", "2,2A,0D",
        "1,travel,,,rad,0.00001,0,0,-999999,999999,1,1,P",
        f"2,{name},,,{unit},0.01,0,0,-999999,999999,1,1,P",
        "50", "1", f"10000,{n}",
        "01/01/2024,00:00:00.000000", "01/01/2024,00:00:00.000000", "ASCII", "1", ""])
    rows = [f"{i + 1},{i * 100},{int(round(travel[i] / 1e-5))},{int(round(temp_values[i] / 0.01))}"
            for i in range(n)]
    return cfg.encode(), ("\n".join(rows) + "\n").encode()


def _read(cfg, dat, channel="mech_temp"):
    return load_comtrade_bytes(cfg, dat, source="upload:rec.cfg", temperature_channel=channel)


def test_a_celsius_channel_gives_the_median_temperature():
    values = np.full(64, 12.5)
    values[3] = 80.0  # one spike does not move the median
    cap = _read(*_record(values))
    assert cap.meta["temperature_c"] == 12.5 and cap.meta["temperature_source"] == "channel"


def test_a_kelvin_channel_is_converted():
    cap = _read(*_record(np.full(64, 263.15), unit="K"))
    assert cap.meta["temperature_c"] == pytest.approx(-10.0)


@pytest.mark.parametrize("values, unit, channel, words", [
    (np.full(64, 12.5), "C", "oil_temp", "no temperature channel named 'oil_temp'"),
    (np.full(64, 12.5), "bar", "mech_temp", "is in 'bar', expected C or K"),
    (np.full(64, 900.0), "C", "mech_temp", "outside -60..100 C"),
])
def test_a_missing_or_odd_channel_is_a_warning_not_a_failure(values, unit, channel, words):
    cap = _read(*_record(values, unit=unit), channel=channel)
    assert "temperature_c" not in cap.meta
    assert any(words in w and "not temperature-compensated" in w for w in cap.meta["warnings"])
    assert cap.travel.size == 64  # the capture itself is fine


def test_without_a_temperature_channel_named_nothing_is_read():
    cap = load_comtrade_bytes(*_record(np.full(64, 12.5)), source="upload:rec.cfg")
    assert "temperature_c" not in cap.meta
