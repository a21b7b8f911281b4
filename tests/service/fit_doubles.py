"""Failure injection for job tests (never used by the product): wrappers around the real fit."""

from __future__ import annotations

import time


def fails_without_motion(capture, breaker, operation, *, dc=None, seed=1):
    """The real fit, but a capture that barely moves fails the way a bad recording does."""
    from service.estimation import FitError, fit_capture

    if float(capture.travel.max() - capture.travel.min()) < 0.1:
        raise FitError("the travel barely moves: no operation to fit")
    return fit_capture(capture, breaker, operation, dc=dc, seed=seed)


def slow_fit(capture, breaker, operation, *, dc=None, seed=1):
    """The real fit after a pause, so a test can kill the worker in the middle of it."""
    from service.estimation import fit_capture

    time.sleep(1.5)
    return fit_capture(capture, breaker, operation, dc=dc, seed=seed)


def celery_double(capture, breaker, operation, *, dc=None, seed=1):
    """For the Celery lane, whose worker runs one fit function for the whole session: the real fit
    (failing on a capture without motion), paused while the file named by HVCB_TEST_SLOW_FILE
    exists, so a test can kill the worker in the middle of a fit."""
    import os
    from pathlib import Path

    flag = os.environ.get("HVCB_TEST_SLOW_FILE")
    if flag and Path(flag).exists():
        time.sleep(2.0)
    return fails_without_motion(capture, breaker, operation, dc=dc, seed=seed)
