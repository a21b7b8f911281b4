"""Retention: pruning never removes a raw capture that an alarm's evidence or a baseline names,
the disk holds exactly what the policy keeps, and a dry run removes nothing."""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import pytest
from sqlalchemy import select

from service.settings import RetentionSettings
from service.storage.db import make_engine, session_factory, upgrade
from service.storage.models import AlarmRow, CapturePreviewRow, DriftStateRow, OperationRow
from service.storage.retention import capture_preview, plan_prune, protected_operations, prune
from service.storage.spool import capture_digest, capture_files

from .history import build_history


@pytest.fixture
def history(empty_db_url, tmp_path):
    upgrade(empty_db_url)
    engine = make_engine(empty_db_url)
    Session = session_factory(engine)
    capture_dir = tmp_path / "data" / "captures"
    info = build_history(Session, capture_dir)
    yield Session, capture_dir, info, empty_db_url
    engine.dispose()


def _disk(capture_dir: Path) -> dict[Path, int]:
    return {p: p.stat().st_size for p in capture_dir.rglob("*") if p.is_file()}


def _opens(op: OperationRow) -> bool:
    """The raw capture is there, reads, and is the one recorded at capture time."""
    from service.acquisition.capture_file import read_capture

    files = capture_files(op.capture_path)
    if not all(p.is_file() for p in files) or capture_digest(files) != op.capture_sha256:
        return False
    return read_capture(op.capture_path).travel.size == op.n_samples


def _evidence_and_baseline_ids(session) -> tuple[set[int], set[int]]:
    evidence, baseline = set(), set()
    for alarm in session.scalars(select(AlarmRow)):
        evidence.update(alarm.evidence["operation_ids"])
        evidence.add(alarm.evidence["current"]["operation_id"])
        evidence.update(alarm.evidence["baseline"]["operation_ids"])
    for row in session.scalars(select(DriftStateRow)):
        baseline.update(row.state["baseline"]["operation_ids"])
    return evidence, baseline


def test_prune_keeps_evidence_and_baselines_and_the_disk_matches_the_policy(history):
    Session, capture_dir, info, _ = history
    policy = RetentionSettings(max_per_breaker=4)
    with Session() as s:
        alarms = list(s.scalars(select(AlarmRow)))
        assert alarms and {a.breaker_id for a in alarms} == {info["breakers"]["leaky"]}, "the drift must alarm"
        evidence, baseline = _evidence_and_baseline_ids(s)
        assert len(baseline) == 2 * 12
        protected = set(protected_operations(s))
        ops = list(s.scalars(select(OperationRow).order_by(OperationRow.occurred_at.desc())))
    assert evidence | baseline <= protected
    keep = set(protected)
    for breaker_id in info["breakers"].values():
        others = [o.id for o in ops if o.breaker_id == breaker_id and o.id not in protected]
        keep.update(others[:4])
    assert len(keep) < len(ops), "the policy must prune something for the test to mean anything"
    before = _disk(capture_dir)

    dry = prune(Session, policy=policy, capture_dir=capture_dir, dry_run=True)
    assert _disk(capture_dir) == before, "a dry run removed files"
    with Session() as s:
        assert s.scalar(select(CapturePreviewRow).limit(1)) is None
    kept_stems = {Path(o.capture_path).with_suffix("") for o in ops if o.id in keep}
    kept_bytes = sum(size for p, size in before.items() if p.with_suffix("") in kept_stems)
    assert dry.captures == len(ops) - len(keep)
    assert dry.bytes_freed == sum(before.values()) - kept_bytes

    report = prune(Session, policy=policy, capture_dir=capture_dir)
    assert (report.captures, report.bytes_freed) == (dry.captures, dry.bytes_freed)
    after = _disk(capture_dir)
    assert sum(after.values()) == kept_bytes
    with Session() as s:
        for op in s.scalars(select(OperationRow)):
            assert _opens(op) == (op.id in keep), f"operation {op.id}"
            preview = s.get(CapturePreviewRow, op.id)
            assert (preview is None) == (op.id in keep)
            if preview is not None:
                assert preview.bytes_freed > 0 and len(preview.preview["t"]) > 50
                assert op.fit.status == "done" and op.fit.parameters  # the fit stays
        assert len(list(s.scalars(select(AlarmRow)))) == len(alarms)

    again = prune(Session, policy=policy, capture_dir=capture_dir)
    assert (again.captures, again.bytes_freed) == (0, 0), "a second run found more to prune"


def test_prune_by_age_and_an_interrupted_run_is_finished(history):
    Session, capture_dir, info, _ = history
    with Session() as s:
        newest = max(s.scalars(select(OperationRow.occurred_at)))
        protected = set(protected_operations(s))
        ops = list(s.scalars(select(OperationRow)))
    policy = RetentionSettings(max_age_days=3)
    now = newest + timedelta(days=1)
    young = {o.id for o in ops if o.occurred_at.replace(tzinfo=newest.tzinfo) >= now - timedelta(days=3)}
    with Session() as s:
        plan = plan_prune(s, policy=policy, capture_dir=capture_dir, now=now)
    planned = {c.operation_id for c in plan.candidates}
    assert planned == {o.id for o in ops} - protected - young
    assert all(c.reason == "age" for c in plan.candidates)

    # an interrupted run: the preview was committed, the files not yet removed
    victim = plan.candidates[0]
    with Session() as s, s.begin():
        s.add(CapturePreviewRow(operation_id=victim.operation_id, bytes_freed=victim.bytes,
                                preview={"t": [0.0], "travel": [0.0], "vibration": None}))
    report = prune(Session, policy=policy, capture_dir=capture_dir, now=now)
    assert report.captures == len(planned)
    assert not any(p.exists() for p in victim.files)


def test_nothing_is_pruned_without_a_policy(history):
    Session, capture_dir, _, _ = history
    before = _disk(capture_dir)
    report = prune(Session, policy=RetentionSettings(), capture_dir=capture_dir)
    assert report.captures == 0 and _disk(capture_dir) == before


def test_preview_keeps_every_peak_and_is_small():
    import numpy as np

    t = np.arange(60_000) / 128_000.0
    travel = np.tanh(t * 40)
    vibration = np.zeros_like(t)
    vibration[31_337] = 420.0  # one-sample shock
    vibration[12_000] = -380.0
    p = capture_preview(t, travel, vibration, sample_rate=128_000.0, buckets=100)
    assert max(p["vibration"]) == 420.0 and min(p["vibration"]) == -380.0
    assert p["travel"][0] == 0.0 and p["travel"][-1] == pytest.approx(travel[-1], abs=1e-6)
    assert len(p["t"]) <= 4 * 100 + 2 and p["n_samples"] == 60_000


def test_hvcb_prune_dry_run_prints_bytes_and_removes_nothing(history, tmp_path, capsys):
    from service.cli import main

    Session, capture_dir, _, url = history
    cfg = tmp_path / "prune.toml"
    cfg.write_text(f'data_dir = "{tmp_path / "data"}"\ndatabase_url = "{url}"\n'
                   f'[retention]\nmax_per_breaker = 4\n')
    before = _disk(capture_dir)
    assert main(["prune", "--dry-run", "--config", str(cfg)]) == 0
    out = capsys.readouterr().out
    with Session() as s:
        expected = plan_prune(s, policy=RetentionSettings(max_per_breaker=4), capture_dir=capture_dir)
    assert f"would free {expected.bytes} bytes" in out
    assert _disk(capture_dir) == before

    assert main(["prune", "--config", str(cfg)]) == 0
    assert f"freed {expected.bytes} bytes" in capsys.readouterr().out
    assert sum(_disk(capture_dir).values()) == sum(before.values()) - expected.bytes

    cfg.write_text(f'data_dir = "{tmp_path / "data"}"\ndatabase_url = "{url}"\n')
    assert main(["prune", "--config", str(cfg)]) == 2
    assert "no retention policy" in capsys.readouterr().err


def test_operation_page_shows_the_preview_of_a_pruned_capture(history, tmp_path):
    import re

    from fastapi.testclient import TestClient

    from service.api.app import create_app
    from service.settings import load_settings

    Session, capture_dir, _, url = history
    prune(Session, policy=RetentionSettings(max_per_breaker=2), capture_dir=capture_dir)
    with Session() as s:
        pruned = s.scalar(select(CapturePreviewRow.operation_id).limit(1))
    settings = load_settings(data_dir=tmp_path / "data", database_url=url, broker_url="", executor="inline",
                             breakers=[], bootstrap_admin_key="upgrade-test-admin-key-0123456789")
    app = create_app(settings, start_monitor=False)
    with TestClient(app) as client:
        r = client.get("/signin")
        csrf = re.search(r'name="csrf_token" value="([^"]+)"', r.text).group(1)
        r = client.post("/signin", data={"api_key": "upgrade-test-admin-key-0123456789", "csrf_token": csrf,
                                         "next": "/"}, follow_redirects=False)
        assert r.status_code == 303, r.text
        page = client.get(f"/operations/{pruned}")
        assert page.status_code == 200 and "raw capture pruned" in page.text
        body = client.get(f"/ui/operations/{pruned}/curves.json").json()
        assert "raw capture pruned" in body["note"]
        assert len(body["measured"]) == len(body["t"]) > 50
        assert max(body["vibration"]["max"]) > 100  # the closing shock survives the decimation


def test_the_service_schedule_prunes_and_stops(history, tmp_path):
    import time

    from service.settings import load_settings
    from service.storage.retention import RetentionSchedule

    Session, capture_dir, _, url = history
    settings = load_settings(data_dir=tmp_path / "data", database_url=url, broker_url="", breakers=[],
                             retention={"max_per_breaker": 4, "interval_s": 0.2})
    schedule = RetentionSchedule(settings, Session, first_after_s=0.0)
    with Session() as s:
        expected = plan_prune(s, policy=settings.retention, capture_dir=capture_dir)
    schedule.start()
    try:
        deadline = time.monotonic() + 60
        while schedule.last_report is None and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        schedule.stop()
    assert schedule.last_report is not None, "the schedule never pruned"
    assert schedule.last_report.bytes_freed == expected.bytes > 0
    assert not schedule._thread.is_alive()
    assert not RetentionSchedule(load_settings(breakers=[], broker_url=""), Session).enabled
