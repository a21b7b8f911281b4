"""Small helpers every study shares: the reference breaker and a process pool."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

REFERENCE_BREAKER = Path(__file__).resolve().parents[2] / "config" / "breakers" / "reference-252kV.toml"
DEFAULT_WORKERS = 2


@lru_cache(maxsize=4)
def load_reference(path: str = str(REFERENCE_BREAKER)):
    """The breaker the studies simulate (loaded once per process)."""
    from ..breaker_file import load_breaker

    return load_breaker(path)


def pool_map(func, tasks, workers: int):
    """``[func(t) for t in tasks]``, in ``workers`` processes when more than one.

    Results come back in task order. Each worker compiles the numba kernels once (cached on disk).
    A progress bar shows on a terminal (stderr), nothing otherwise.
    """
    from ..processes import process_pool
    from ..progress import track

    tasks = list(tasks)
    desc = getattr(func, "__name__", "tasks").replace("_", " ")
    if workers <= 1 or len(tasks) <= 1:
        return [func(t) for t in track(tasks, desc=desc, unit="task")]
    with process_pool(min(workers, len(tasks)), start_method=None) as ex:
        return list(track(ex.map(func, tasks, chunksize=1), total=len(tasks), desc=desc, unit="task"))
