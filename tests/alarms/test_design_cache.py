"""The CUSUM thresholds are designed once per settings and kept (service/alarms/design_cache.py)."""
import json

import pytest

from service.alarms import design, design_cache
from service.alarms.settings import DriftSettings


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("HVCB_CACHE_DIR", str(tmp_path))
    design_cache.clear_memory()
    yield tmp_path / design_cache.FILE_NAME
    design_cache.clear_memory()


def test_the_shipped_thresholds_are_the_designed_ones():
    shipped = json.loads(design_cache.SHIPPED.read_text())
    s = DriftSettings()
    for arl in (s.sides * 1e4 / s.design_false_warnings_per_10k, s.sides * 1e4 / s.design_false_alarms_per_10k):
        name = design_cache.key(arl, k=s.k, z_cap=s.z_cap)
        assert name in shipped, "the default settings' thresholds ship with the package"
        fresh = design.threshold_for_arl.__wrapped__(arl, k=s.k, z_cap=s.z_cap)
        assert shipped[name] == pytest.approx(fresh, abs=1e-5)


def test_the_default_settings_load_without_designing(cache, monkeypatch):
    def refuse(*a, **k):
        raise AssertionError("designed a threshold the package ships")
    monkeypatch.setattr(design, "threshold_for_arl", refuse)
    s = DriftSettings()
    assert 1.0 < s.h_warning < s.h_alarm
    assert not cache.exists(), "nothing to store: both came from the shipped file"


def test_new_settings_are_designed_once_then_read_from_disk(cache, monkeypatch):
    calls = []
    real = design.threshold_for_arl

    def counted(arl, *, k, z_cap):
        calls.append((arl, k, z_cap))
        return real(arl, k=k, z_cap=z_cap)

    monkeypatch.setattr(design, "threshold_for_arl", counted)
    first = DriftSettings(k=1.0, z_cap=2.5)
    h = (first.h_warning, first.h_alarm)
    assert len(calls) == 2 and cache.exists()
    stored = json.loads(cache.read_text())
    assert design_cache.key(calls[0][0], k=1.0, z_cap=2.5) in stored
    design_cache.clear_memory()  # a new process: only the disk is left
    again = DriftSettings(k=1.0, z_cap=2.5)
    assert (again.h_warning, again.h_alarm) == h
    assert len(calls) == 2, "the second load read the cache instead of designing again"


def test_a_corrupt_cache_is_designed_again(cache, monkeypatch):
    cache.parent.mkdir(parents=True, exist_ok=True)
    cache.write_text("{not json")
    h = design_cache.threshold(5000.0, k=1.0, z_cap=2.5)
    assert h == pytest.approx(design.threshold_for_arl(5000.0, k=1.0, z_cap=2.5))
    assert design_cache.key(5000.0, k=1.0, z_cap=2.5) in json.loads(cache.read_text())


def test_the_key_holds_everything_the_threshold_depends_on():
    base = design_cache.key(1e5, k=1.25, z_cap=3.0)
    others = {design_cache.key(1e5 + 1, k=1.25, z_cap=3.0), design_cache.key(1e5, k=1.2, z_cap=3.0),
              design_cache.key(1e5, k=1.25, z_cap=3.5)}
    assert base not in others and len(others) == 3
    assert design_cache.DESIGN_VERSION in base
