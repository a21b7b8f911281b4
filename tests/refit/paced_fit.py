"""Failure injection for the interruption test (never used by the product): the real fit,
paced so that a test can interrupt a refit while batches are landing."""

import time


def paced_fit(capture, breaker, operation, *, dc=None, seed=1, prior=None):
    from service.estimation import fit_capture

    time.sleep(0.05)
    return fit_capture(capture, breaker, operation, dc=dc, seed=seed, prior=prior)
