"""The reference breaker's nominal constants, read once from its breaker file."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from .mechanism import Mechanism

REFERENCE_BREAKER = Path(__file__).resolve().parents[3] / "config" / "breakers" / "reference-252kV.toml"


@lru_cache(maxsize=4)
def reference_mechanism(path: str | None = None) -> Mechanism:
    """Nominal constants of a breaker file (the reference 252 kV breaker by default)."""
    from service.breaker_file import load_breaker

    return Mechanism.from_breaker(load_breaker(path or REFERENCE_BREAKER))
