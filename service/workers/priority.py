"""The CPU priority of the workers that draw reports and run diagnoses: below the API's, so the
light routes keep answering while they work (issue 44 item 2). Fits keep the API's priority:
their result is what the page waits for."""

from __future__ import annotations

import os

BACKGROUND_NICE = 10  # added to the API's niceness in each worker process


def lower_priority() -> None:
    """A process-pool initializer: this worker runs ``BACKGROUND_NICE`` steps nicer."""
    try:
        os.nice(BACKGROUND_NICE)
    except OSError:  # not permitted here: the work still runs, at the API's priority
        pass
