"""The reader decodes binary COMTRADE data itself (the package spends most of its time on per-sample
times the reader does not use): every value must equal what the ``comtrade`` package gives."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.comtrade import record
from drivers.emulators.sources import NOMINAL
from service.acquisition.comtrade_writer import write_comtrade
from drivers.synthetic import synthesize_capture
from tests.acquisition.test_field_comtrade import FOLDERS, _capture_file, _folder
from tests.conftest import shared_dir


def _assert_same_as_package(path, monkeypatch):
    fast = record.read_record(path)
    with monkeypatch.context() as m:
        m.setattr(record, "_channel_values", record._package_values)
        slow = record.read_record(path)
    assert len(fast.analog) == len(slow.analog) and len(fast.digital) == len(slow.digital)
    for a, b in zip(fast.analog, slow.analog):
        assert a.dtype == np.float64 and np.array_equal(a, b, equal_nan=True)
    for a, b in zip(fast.digital, slow.digital):
        assert np.array_equal(a, b)
    return fast


BINARY_FOLDERS = [f for f in FOLDERS if "ascii" not in f and "83rates" not in f]


@pytest.mark.parametrize("folder", BINARY_FOLDERS)
def test_real_binary_records_decode_exactly_as_the_package_does(folder, monkeypatch):
    rec = _assert_same_as_package(_capture_file(_folder(folder)), monkeypatch)
    assert rec.header.file_type in ("BINARY", "BINARY32", "FLOAT32")


def test_shared_samples_decode_exactly_as_the_package_does(monkeypatch):
    files = sorted((shared_dir() / "samples").rglob("*.cfg"))
    if not files:
        pytest.skip(f"shared samples not found under {shared_dir()} (set HVCB_SHARED_DIR)")
    for path in files:
        _assert_same_as_package(path, monkeypatch)


@pytest.mark.parametrize("fmt", ["BINARY", "BINARY32", "FLOAT32"])
def test_own_captures_decode_exactly_as_the_package_does(breaker, tmp_path, fmt, monkeypatch):
    cap, _ = synthesize_capture(breaker, "open", NOMINAL["open"], rng=np.random.default_rng(3))
    path = write_comtrade(cap, tmp_path, "op", format=fmt)
    rec = _assert_same_as_package(path, monkeypatch)
    assert rec.header.file_type == fmt and rec.samples == cap.travel.size
