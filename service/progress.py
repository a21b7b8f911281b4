"""Progress bars for long jobs: shown on a terminal, silent when the output is not a TTY."""

from __future__ import annotations

import sys


def progress(total: int | None = None, *, desc: str = "", unit: str = "it", stream=None,
             initial: int = 0):
    """A tqdm bar with rate and time left on ``stream`` (stderr), disabled unless it is a TTY.

    The caller drives it with ``update(n)`` and closes it (or uses it as a context manager).
    """
    from tqdm import tqdm

    class Bar(tqdm):
        monitor_interval = 0  # no monitor thread: the bar refreshes on update

    stream = stream if stream is not None else sys.stderr
    tty = bool(getattr(stream, "isatty", lambda: False)())
    return Bar(total=total, desc=desc, unit=unit, file=stream, disable=not tty, initial=initial,
               ncols=_columns(stream) if tty else None, smoothing=0.1)


def _columns(stream) -> int:
    """The terminal's width; 100 when it reports none (a fresh pty)."""
    import os

    try:
        return os.get_terminal_size(stream.fileno()).columns or 100
    except (OSError, ValueError, AttributeError):
        return 100


def track(iterable, *, total: int | None = None, desc: str = "", unit: str = "it", stream=None):
    """Iterate with a progress bar (see :func:`progress`)."""
    if total is None:
        try:
            total = len(iterable)
        except TypeError:
            total = None
    bar = progress(total, desc=desc, unit=unit, stream=stream)
    try:
        for item in iterable:
            yield item
            bar.update(1)
    finally:
        bar.close()
