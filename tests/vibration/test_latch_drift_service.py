"""The latch time through the service's drift detector and prognosis, on a real (SQLite) database:
fits whose characteristics carry a latch time that grows raise the latch alarm with its cause in
words, and the breaker file's [vibration] limit in ms gives a prognosis. No migration: the values
live in the fits' JSON characteristics."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest
from sqlalchemy import select

from service.alarms.settings import DriftSettings
from service.breaker_file import BreakerFileError, parse_breaker_text
from service.jobs.fit import update_drift
from service.jobs.prognosis import breaker_prognoses
from service.storage import crud
from service.storage.db import cached_engine, session_factory, upgrade
from service.storage.models import AlarmRow
from tests.conftest import BREAKER_FILE

SETTINGS = DriftSettings(baseline_n=10, watched={"DO": "falling", "latch_time_s": "rising"})
T0 = datetime(2026, 1, 1, tzinfo=timezone.utc)


def _with_latch_limit(ms) -> str:
    """The reference breaker file with its [vibration] latch limit set to ``ms``."""
    text = BREAKER_FILE.read_text()
    assert "latch_time_max_ms = 2.3" in text
    return text.replace("latch_time_max_ms = 2.3", f"latch_time_max_ms = {ms}")


def test_vibration_limit_in_ms_and_its_refusals():
    limits = parse_breaker_text(_with_latch_limit(2.5), source="b.toml").limits
    assert limits.root["latch_time_s"].max == pytest.approx(2.5e-3)
    with pytest.raises(BreakerFileError, match="b.toml.*latch_time_max_ms"):
        parse_breaker_text(_with_latch_limit(0), source="b.toml")


@pytest.fixture
def session_maker(tmp_path):
    url = f"sqlite:///{tmp_path / 'hvcb.sqlite3'}"
    upgrade(url)
    Session = session_factory(cached_engine(url))
    text = _with_latch_limit(2.5)
    cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
    with Session() as s, s.begin():
        crud.upsert_breaker(s, name="reference-252kV", tag="Q1", breaker_file=text,
                            cam_file_name="reference-252kV.cam.csv", cam_table=cam)
    return Session


def _store(Session, i, latch, events, do=39.5):
    with Session() as s, s.begin():
        op, _ = crud.create_operation(s, capture_key=f"latch{i}", breaker_id=1, kind="open",
                                      occurred_at=T0 + timedelta(hours=i), source="replay",
                                      capture_path="/nonexistent.cfg", capture_sha256="0" * 64, flags=[],
                                      sample_rate=1.0, n_samples=1)
        crud.claim_fit(s, operation_id=op.id, worker="test")
        crud.store_fit_result(s, operation_id=op.id, curve=None, result={
            "parameters": {"AO": 3424.0, "BO": 4806.0, "DO": do, "EO": 3950.0},
            "ci95": {"DO": [do - 0.3, do + 0.3]}, "identifiable": True,
            "characteristics": {"latch_time_s": latch, "vibration_events": events}})
        return update_drift(s, breaker_id=1, settings=SETTINGS)


def test_a_sticking_latch_raises_its_alarm_and_gets_a_prognosis(session_maker):
    rng = np.random.default_rng(5)
    raised_at = None
    for i in range(40):
        latch = 1.2e-3 * (1 + rng.normal(0, 0.02)) + (max(0, i - 20 + 1) * 0.04e-3 if i >= 20 else 0.0)
        events = [{"name": "first_shock", "t_s": -latch, "peak_g": 30.0, "clipped": False},
                  {"name": "latch_release", "t_s": -0.4e-3, "peak_g": 400.0, "clipped": False}]
        evs = _store(session_maker, i, latch, events, do=39.5 * (1 + rng.normal(0, 0.003)))
        if raised_at is None and any(e.kind == "raised" and e.parameter == "latch_time_s" for e in evs):
            raised_at = i
    assert raised_at is not None and 20 <= raised_at < 20 + 15
    with session_maker() as s:
        alarm = s.scalar(select(AlarmRow).where(AlarmRow.parameter == "latch_time_s"))
        assert "trip latch is slow" in alarm.message
        b = crud.get_breaker(s, breaker_id=1)
        progs = {p.parameter: p for p in breaker_prognoses(s, breaker=b, settings=SETTINGS)}
    latch = progs["latch_time_s"]
    assert latch.status == "ok", latch
    assert latch.operations_to_limit is not None and latch.operations_to_limit.median is not None
    # 1.2 ms + 0.04 ms per opening reaches 2.5 ms some 12 openings after the 40th
    assert 3 <= latch.operations_to_limit.median <= 25


def test_a_missed_strike_is_not_fed_to_the_detector(session_maker):
    events = [{"name": "first_shock", "t_s": -1.2e-3, "peak_g": 30.0, "clipped": False},
              {"name": "latch_release", "t_s": -0.4e-3, "peak_g": 400.0, "clipped": False}]
    for i in range(5):
        _store(session_maker, i, 1.2e-3, events)
    missed = [{"name": "first_shock", "t_s": -0.41e-3, "peak_g": 400.0, "clipped": False}]
    _store(session_maker, 5, 0.41e-3, missed)
    from service.storage.crud_vibration import latch_history

    with session_maker() as s:
        values = [r.value for r in latch_history(s, breaker_id=1)]
    assert len(values) == 5 and min(values) == pytest.approx(1.2e-3)


def test_the_condition_report_has_the_latch_and_coil_section(session_maker, tmp_path):
    import shutil
    import subprocess

    if shutil.which("pdftotext") is None:
        pytest.skip("report lane off: poppler-utils (pdftotext) not installed")
    from service.reports.content import gather
    from service.reports.pdf import report_pdf

    events = [{"name": "first_shock", "t_s": -1.234e-3, "peak_g": 30.0, "clipped": False},
              {"name": "latch_release", "t_s": -0.4e-3, "peak_g": 400.0, "clipped": False}]
    for i in range(3):
        _store(session_maker, i, 1.234e-3, events)
    with session_maker() as s, s.begin():  # the latest opening: a record with a trip coil, no vibration
        op, _ = crud.create_operation(s, capture_key="coil", breaker_id=1, kind="open", occurred_at=T0 + timedelta(days=1),
                                      source="upload", capture_path="/nonexistent.csv", capture_sha256="1" * 64,
                                      flags=[], sample_rate=1.0, n_samples=1)
        crud.claim_fit(s, operation_id=op.id, worker="test")
        crud.store_fit_result(s, operation_id=op.id, curve=None, result={
            "parameters": {"AO": 3424.0, "BO": 4806.0, "DO": 39.5, "EO": 3950.0}, "identifiable": True,
            "characteristics": {"latch_time_s": None, "latch_time_reason": "no vibration channel in the capture",
                                "vibration_events": [],
                                "coils": [{"channel": "C4", "pulse": 0, "energised_s": 0.3, "peak_current_a": 1.433,
                                           "armature_dip_s": 0.012, "current_end_s": 0.0257,
                                           "analyser_peak_a": 1.42, "peak_difference_rel": 0.009}]}})
    with session_maker() as s:
        content = gather(s, breaker=crud.get_breaker(s, breaker_id=1), settings=SETTINGS)
    out = tmp_path / "r.pdf"
    report_pdf(content, out)
    text = subprocess.run(["pdftotext", "-raw", str(out), "-"], capture_output=True, text=True).stdout
    assert "Trip latch and coil currents" in text
    assert "no latch time: no vibration channel in the capture" in text
    assert "C4 1.433 1.420 (+0.9%) 12.0 25.7" in text
