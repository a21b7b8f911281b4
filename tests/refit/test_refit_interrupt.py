"""``hvcb refit`` interrupted by SIGINT and by SIGKILL, then run again: every operation ends
with exactly one current result (and its superseded one kept)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from sqlalchemy import select

from service.storage.db import make_engine, session_factory
from service.storage.models import RefitRunRow
from tests.refit.fleet import seed_history
from tests.refit.test_refit import assert_one_current_result_each

REPO = Path(__file__).resolve().parents[2]
N = 48


def _refit(db_url, data_dir):
    env = dict(os.environ, DATABASE_URL=db_url, HVCB_DATA_DIR=str(data_dir),
               HVCB_FIT_FUNCTION="paced_fit:paced_fit",
               PYTHONPATH=os.pathsep.join([str(REPO), str(REPO / "tests" / "refit")]))
    return subprocess.Popen([sys.executable, "-m", "service.cli", "refit", "--workers", "1",
                             "--batch-size", "3"], cwd=REPO, env=env, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_interruptible)


def _interruptible() -> None:
    """Ctrl-C as on a terminal: a suite started in the background (``cmd &`` in a script, as CI
    may) passes SIGINT on ignored, and Python then never raises KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _run(Session):
    with Session() as s:
        return s.scalar(select(RefitRunRow).order_by(RefitRunRow.id.desc()).limit(1))


def _wait_landed(Session, proc, more_than, timeout=120):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        run = _run(Session)
        if run is not None and run.done > more_than:
            return run.done
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    raise AssertionError("the refit landed nothing in time")


def test_sigint_then_sigkill_then_resume_lands_every_result_exactly_once(db_url, tmp_path, breaker):
    engine = make_engine(db_url)
    Session = session_factory(engine)
    try:
        ids = seed_history(Session, breaker, tmp_path / "captures", N, per_kind=2)

        proc = _refit(db_url, tmp_path / "data")
        landed = _wait_landed(Session, proc, 0)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C reaches the whole foreground group
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 130, (out, err)
        assert "interrupted; run the same command again to resume" in err
        run = _run(Session)
        assert run.status == "interrupted" and landed <= run.done < N

        proc = _refit(db_url, tmp_path / "data")
        _wait_landed(Session, proc, run.done)
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=60)
        time.sleep(0.5)  # an orphaned worker's last transaction, if any, commits or rolls back
        killed = _run(Session)
        assert killed.id == run.id and killed.status == "running" and killed.done < N

        proc = _refit(db_url, tmp_path / "data")
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, (out, err)
        assert f"resuming refit run {run.id}" in out
        assert "fit/s" not in err and "%|" not in err  # no progress bar when not on a terminal
        assert_one_current_result_each(Session, ids, run.id)
    finally:
        engine.dispose()
