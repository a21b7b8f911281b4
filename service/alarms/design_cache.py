"""The CUSUM decision thresholds, designed once per settings and kept: in memory, in a file that
ships with the package (the default settings' thresholds), and in the user's cache directory.

Designing a threshold (``design.threshold_for_arl``: a Brook-Evans Markov chain of 300 states
solved inside a root search) takes about 1.5 s for the two of a settings object, and importing
SciPy for it another second or so; a CLI command that loads the settings should not pay it.
A threshold depends only on the target run length, k, z_cap, the chain's size and the design
method itself, so it is stored under exactly that key (``key``), with ``DESIGN_VERSION`` naming
the method: changing how thresholds are computed means changing that version, which makes every
stored value unreachable rather than wrong.

This is the only module of service.alarms that touches files. Reading or writing the cache never
fails a caller: an unreadable or unwritable cache (a read-only home, a corrupt file) only means
the threshold is designed again.

Cache directory: ``$HVCB_CACHE_DIR``, else ``$XDG_CACHE_HOME/hvcb``, else ``~/.cache/hvcb``.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import threading
from pathlib import Path

# Name of the design method; bump when design.py's computation changes (chain size, root search).
DESIGN_VERSION = "brook-evans-300/brentq-1e-6/v1"
N_STATES = 300
SHIPPED = Path(__file__).with_name("thresholds.json")
FILE_NAME = "cusum_thresholds.json"

_memory: dict[str, float] = {}
_lock = threading.Lock()


def key(arl: float, *, k: float, z_cap: float) -> str:
    """The cache key of one threshold: everything it depends on, floats written exactly."""
    return f"{DESIGN_VERSION}|arl={float(arl)!r}|k={float(k)!r}|z_cap={float(z_cap)!r}|states={N_STATES}"


def cache_dir() -> Path:
    if os.environ.get("HVCB_CACHE_DIR"):
        return Path(os.environ["HVCB_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "hvcb"


def _read(path: Path) -> dict[str, float]:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    return {k: float(v) for k, v in data.items()
            if isinstance(k, str) and isinstance(v, (int, float)) and math.isfinite(v) and v > 0}


def _write(path: Path, entries: dict[str, float]) -> None:
    """Merge ``entries`` into the file at ``path``, atomically (write a temporary file, rename)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        merged = {**_read(path), **entries}
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".cusum-", suffix=".json")
        with os.fdopen(fd, "w") as f:
            json.dump(merged, f, indent=1, sort_keys=True)
        os.replace(tmp, path)
    except OSError:
        pass


def threshold(arl: float, *, k: float, z_cap: float) -> float:
    """Decision threshold h [z] whose one-sided in-control ARL is ``arl`` [fits]: from memory, the
    shipped file or the user's cache when stored there, else designed (design.threshold_for_arl)
    and stored."""
    name = key(arl, k=k, z_cap=z_cap)
    with _lock:
        if name in _memory:
            return _memory[name]
        for path in (SHIPPED, cache_dir() / FILE_NAME):
            found = _read(path).get(name)
            if found is not None:
                _memory[name] = found
                return found
    from service.alarms.design import threshold_for_arl

    h = threshold_for_arl(arl, k=k, z_cap=z_cap)
    with _lock:
        _memory[name] = h
    _write(cache_dir() / FILE_NAME, {name: h})
    return h


def clear_memory() -> None:
    """Forget the in-memory thresholds (tests)."""
    with _lock:
        _memory.clear()
