"""The report's alarms: an acknowledged and shelved alarm shows its lifecycle (who, when, why)
from the audit trail, and a shelved alarm does not count in the summary's status, as on the page."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from .conftest import BREAKER_FILE


def _leak_history(tmp_path, n: int):
    """A migrated SQLite database with the reference breaker and ``n`` operations of a buffer leak
    (its DO alarm raised): (session factory, settings)."""
    from service.breaker_file import load_breaker
    from service.settings import load_settings
    from service.storage import crud
    from service.storage.db import make_engine, session_factory, upgrade

    from .history import bulk_history

    url = f"sqlite:///{tmp_path / 'hvcb.sqlite3'}"
    upgrade(url)
    settings = load_settings(data_dir=tmp_path, database_url=url, broker_url="", executor="inline",
                             bootstrap_admin_key=None)
    Session = session_factory(make_engine(url))
    with Session() as s, s.begin():
        crud.register_breaker_file(s, path=BREAKER_FILE, tag="Q1")
    bulk_history(Session, settings.drift_settings, load_breaker(BREAKER_FILE), capture_path="/nonexistent.cfg",
                 n=n, leak_from=0.5, leak_per_op=0.97)
    return Session, settings


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="report lane off: pdftotext not installed")
def test_the_lifecycle_and_the_shelve_are_in_the_report(tmp_path):
    from service.jobs.alarm_actions import audit_acknowledge, shelve
    from service.reports.content import gather
    from service.reports.pdf import render
    from service.storage import crud

    Session, settings = _leak_history(tmp_path, n=200)

    def report_text() -> str:
        with Session() as s:
            c = gather(s, breaker=crud.get_breaker(s, breaker_id=1), settings=settings.drift_settings)
        out = subprocess.run(["pdftotext", "-raw", "-", "-"], input=render(c), capture_output=True, check=True)
        return re.sub(r"\s+", " ", out.stdout.decode())

    before = report_text()
    assert "Alarms ALARM: 1 active (buffer damping (DO) alarm)" in before
    with Session() as s, s.begin():
        alarm = crud.list_alarms(s, state="active", breaker_id=1)[0]
        crud.acknowledge_alarm(s, alarm=alarm, by="j.smith", comment="buffer checked on site")
        audit_acknowledge(s, alarm=alarm, by="j.smith", comment="buffer checked on site")
        shelve(s, alarm=alarm, by="a.jones", minutes=120, reason="buffer replacement booked")
        alarm_id = alarm.id
    after = report_text()
    assert "Alarms none annunciated: 1 active, all shelved (buffer damping (DO) alarm (shelved))" in after
    assert "acknowledged (shelved until" in after
    assert re.search(r"by j\.smith \(buffer checked on site\)", after)
    assert re.search(rf"#{alarm_id} buffer damping \(DO\) ALARM acknowledged raised .* shelve\w* .* by a\.jones \(buffer replacement booked\)",
                     after)


def test_figures_drawn_in_several_threads_at_once_are_the_figures_drawn_alone(tmp_path):
    """The API renders reports in worker threads: the figures use no shared pyplot state."""
    from concurrent.futures import ThreadPoolExecutor

    from service.reports import figures
    from service.reports.content import gather
    from service.storage import crud

    Session, settings = _leak_history(tmp_path, n=120)
    with Session() as s:
        c = gather(s, breaker=crud.get_breaker(s, breaker_id=1), settings=settings.drift_settings)
    alone = (figures.trends_png(c.trends), figures.fan_png(c.prognoses))
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(lambda _: (figures.trends_png(c.trends), figures.fan_png(c.prognoses)), range(8)))
    assert alone[0] and alone[1]
    assert all(t == alone for t in together)
