"""Both cores for the diagnosis (issue 48 item 4): a map over the captures in threads.

The time of a diagnosis is 70-95 % the compiled RK4 of the model curve
(``mechanics.effects.dynamics.integrate_rk4``, 0.3-0.9 ms a call, thousands of calls: the
tally in ``mechanics.effects.integrator`` counts them), compiled with ``nogil=True``: two threads run two captures' curves at once, with no copy of the
captures (a process pool would pickle each capture's window and Jacobians per task). The work
of one capture (its signatures, its Jacobian columns, its residual) is one task, so the order
of the results, and with it every sum, is the serial one: the answer does not depend on the
number of threads.

``HVCB_DIAGNOSIS_THREADS`` sets the threads (default: the machine's cores, at most 2); the gap
corpus, which runs one diagnosis per process on each core, sets it to 1.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_LOCK = threading.Lock()
_POOL: dict = {}
_LOCAL = threading.local()   # a task already on a pool thread maps serially (no nested pools)


def threads() -> int:
    """The threads a map uses: ``HVCB_DIAGNOSIS_THREADS`` or min(2, cores)."""
    raw = os.environ.get("HVCB_DIAGNOSIS_THREADS")
    if raw is not None:
        try:
            n = int(raw)
        except ValueError:
            raise ValueError(f"HVCB_DIAGNOSIS_THREADS must be a whole number, got {raw!r}") from None
        return max(n, 1)
    return max(1, min(2, os.cpu_count() or 1))


def _pool(n: int) -> ThreadPoolExecutor:
    with _LOCK:
        pid = os.getpid()              # a forked child does not inherit a working pool
        key = (pid, n)
        if key not in _POOL:
            _POOL[key] = ThreadPoolExecutor(max_workers=n, thread_name_prefix="hvcb-diagnosis",
                                            initializer=_mark)
        return _POOL[key]


def _mark():
    _LOCAL.inside = True


def pmap(fn, items) -> list:
    """``[fn(x) for x in items]``, the items shared over ``threads()`` threads (in order)."""
    items = list(items)
    n = threads()
    if n == 1 or len(items) < 2 or getattr(_LOCAL, "inside", False):
        return [fn(x) for x in items]
    return list(_pool(min(n, len(items))).map(fn, items))
