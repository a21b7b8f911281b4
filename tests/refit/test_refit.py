"""Refit runs on a real database (SQLite always, PostgreSQL when configured)."""

from __future__ import annotations

from collections import Counter

import pytest
from sqlalchemy import func, select

from service.refit import pool
from service.refit.runs import pending_batches, run_refit, start_run
from service.storage.db import make_engine, session_factory
from service.storage.models import (AlarmRow, FitRow, FitVersionRow, ParameterValueRow, RefitRunRow)
from tests.refit.fleet import seed_history


@pytest.fixture
def fleet(db_url, tmp_path, breaker):
    engine = make_engine(db_url)
    Session = session_factory(engine)
    ids = seed_history(Session, breaker, tmp_path / "captures", 12, per_kind=2)
    yield Session, ids
    engine.dispose()


def _options(db_url):
    from service.jobs.fit import JobOptions

    return JobOptions(database_url=db_url)


def assert_one_current_result_each(Session, ids, run_id, version=2):
    """Every operation: one fits row, refitted by the run, one parameter set, history kept."""
    with Session() as s:
        fits = list(s.scalars(select(FitRow).where(FitRow.operation_id.in_(ids))))
        assert sorted(f.operation_id for f in fits) == sorted(ids)
        assert all(f.refit_run_id == run_id and f.version == version and f.status == "done" for f in fits)
        archived = Counter(v.operation_id for v in s.scalars(select(FitVersionRow)))
        assert all(archived[i] == version - 1 for i in ids), archived
        per_fit = Counter(s.scalars(select(ParameterValueRow.fit_id)))
        assert {per_fit[f.id] for f in fits} <= {3, 4} and all(per_fit[f.id] == len(f.parameters) for f in fits)
        run = s.get(RefitRunRow, run_id)
        assert run.status == "done" and run.done == len(ids) and run.failed == 0


def test_refit_supersedes_every_result_once_and_keeps_the_old_one(fleet, db_url):
    Session, ids = fleet
    with Session() as s, s.begin():
        old = {f.operation_id: f.result for f in s.scalars(select(FitRow))}
        run, resumed = start_run(s, requested_by="test")
        run_id = run.id
    assert not resumed
    seen = []
    run = run_refit(Session, run_id, submit_batches=pool.inline(_options(db_url)),
                    on_progress=lambda n, total: seen.append((n, total)))
    assert_one_current_result_each(Session, ids, run_id)
    assert sum(n for n, _ in seen[1:]) == len(ids) and seen[0] == (0, len(ids))
    with Session() as s:
        for v in s.scalars(select(FitVersionRow)):
            assert v.version == 1 and v.result == old[v.operation_id]
            assert v.superseded_by_run == run_id
        fits = {f.operation_id: f for f in s.scalars(select(FitRow))}
        # The new results are the warm-started estimator's: same answer, far fewer evaluations.
        for op_id, f in fits.items():
            assert f.result["start"].startswith("warm start from")
            for name, value in f.parameters.items():
                assert value == pytest.approx(old[op_id]["parameters"][name], rel=0.02)


def test_a_second_run_makes_version_three_and_the_same_command_resumes(fleet, db_url):
    Session, ids = fleet
    opts = _options(db_url)
    with Session() as s, s.begin():
        first = start_run(s)[0].id
    run_refit(Session, first, submit_batches=pool.inline(opts))
    with Session() as s, s.begin():
        second, resumed = start_run(s)
        second = second.id
    assert not resumed and second != first
    # Stop after the first batch, as an interrupted command would.
    with Session() as s, s.begin():
        batches = pending_batches(s, s.get(RefitRunRow, second), batch_size=5)
    assert [len(b) for b in batches] == [5, 5, 2]

    def interrupted(run_id, all_batches, report):
        from service.jobs.refit import refit_batch

        report(refit_batch(run_id, batches[0], opts)["done"])
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_refit(Session, second, submit_batches=interrupted)
    with Session() as s, s.begin():
        assert s.get(RefitRunRow, second).status == "interrupted"
        again, resumed = start_run(s)
        assert resumed and again.id == second and again.done == len(batches[0])
        assert sum(map(len, pending_batches(s, again))) == len(ids) - 5
    run_refit(Session, second, submit_batches=pool.inline(opts))
    assert_one_current_result_each(Session, ids, second, version=3)


def test_a_batch_landed_twice_counts_once(fleet, db_url):
    from service.jobs.refit import refit_batch

    Session, ids = fleet
    with Session() as s, s.begin():
        run_id = start_run(s)[0].id
    first = refit_batch(run_id, ids[:4], _options(db_url))
    again = refit_batch(run_id, ids[:4], _options(db_url))
    assert first["done"] == 4
    assert (again["done"], again["failed"], again["skipped"], again["fit_s"]) == (0, 0, 4, 0.0)
    with Session() as s:
        assert s.scalar(select(func.count()).select_from(FitVersionRow)) == 4
        assert s.get(RefitRunRow, run_id).done == 4


def test_missing_capture_keeps_the_current_result_and_says_why(fleet, db_url):
    from service.storage.models import OperationRow

    Session, ids = fleet
    with Session() as s, s.begin():
        s.get(OperationRow, ids[0]).capture_path = "/nonexistent/gone.cfg"
        run_id = start_run(s)[0].id
    run = run_refit(Session, run_id, submit_batches=pool.inline(_options(db_url)))
    assert run.failed == 1 and run.done == len(ids) - 1
    assert f"operation {ids[0]}: capture unusable: capture file missing" in run.reason
    with Session() as s:
        fit = s.scalar(select(FitRow).where(FitRow.operation_id == ids[0]))
        assert fit.version == 1 and fit.status == "done" and fit.refit_run_id == run_id


def test_drift_alarms_follow_the_newest_version(fleet, db_url):
    from service.storage.models import AlarmRow as A, utcnow

    Session, ids = fleet
    with Session() as s, s.begin():
        stale = A(breaker_id=1, parameter="DO", level="warning", state="raised", episode=1,
                  message="from superseded results", evidence={}, raised_at=utcnow(), updated_at=utcnow())
        s.add(stale)
        run_id = start_run(s)[0].id
    run_refit(Session, run_id, submit_batches=pool.inline(_options(db_url)))
    with Session() as s:
        alarm = s.scalar(select(AlarmRow).where(AlarmRow.message == "from superseded results"))
        assert alarm.state == "cleared" and alarm.evidence["cleared"]["reason"].startswith("refit")
        # The healthy history raises nothing anew.
        assert s.scalar(select(func.count()).select_from(AlarmRow).where(AlarmRow.state != "cleared")) == 0


def test_unknown_breaker_is_a_sentence(fleet):
    from service.errors import UserError

    Session, _ = fleet
    with Session() as s, pytest.raises(UserError, match="no breaker named 'nope'"):
        start_run(s, breaker="nope")
