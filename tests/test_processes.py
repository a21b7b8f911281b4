"""The service's process pools leave Ctrl-C to the parent: a SIGINT that reaches a worker (the
terminal sends it to the whole process group) neither kills it nor prints a traceback."""

from __future__ import annotations

import os
import signal

from service.processes import process_pool


def _pid() -> int:
    return os.getpid()


def test_a_pool_worker_survives_sigint_and_keeps_working():
    with process_pool(1) as pool:
        pid = pool.submit(_pid).result(timeout=120)
        assert pid != os.getpid()
        os.kill(pid, signal.SIGINT)
        assert pool.submit(_pid).result(timeout=120) == pid  # the same worker, alive


def test_the_initializer_still_runs_in_each_worker():
    with process_pool(1, initializer=_mark) as pool:
        assert pool.submit(_marked).result(timeout=120) == "warm"


def _mark() -> None:
    os.environ["HVCB_TEST_POOL_WARM"] = "warm"


def _marked() -> str:
    return os.environ.get("HVCB_TEST_POOL_WARM", "cold")


def _sigint_state():
    return signal.getsignal(signal.SIGINT), signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])


def test_a_worker_ignores_sigint_and_the_callers_mask_is_restored():
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    with process_pool(1) as pool:
        handler, blocked = pool.submit(_sigint_state).result(timeout=120)
    assert handler == signal.SIG_IGN and not blocked  # ignored, and not left blocked
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == before
