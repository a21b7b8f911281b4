"""The time window a report or an export covers (``--from`` / ``--to``, ``from`` / ``to``)."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timezone


def utc(t: datetime | None) -> datetime | None:
    """``t`` as an aware UTC time; a naive time is taken as UTC."""
    if t is None:
        return None
    try:
        return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)
    except OverflowError:  # 0001-01-01 at +05:00 is before year 1 in UTC
        raise ValueError(f"{t.isoformat()} is outside the years 1 to 9999 in UTC") from None


def iso_z(t: datetime | None) -> str:
    """ISO 8601 in UTC with a ``Z`` (as the API writes times); empty for None."""
    if t is None:
        return ""
    return utc(t).isoformat().replace("+00:00", "Z")


@dataclass(frozen=True)
class Window:
    """Operations with ``start <= occurred_at <= end``; None is open-ended."""

    start: datetime | None = None
    end: datetime | None = None

    def __post_init__(self):
        object.__setattr__(self, "start", utc(self.start))
        object.__setattr__(self, "end", utc(self.end))
        if self.start is not None and self.end is not None and self.start > self.end:
            raise ValueError(f"the window's start {iso_z(self.start)} is after its end {iso_z(self.end)}")

    def where(self, column) -> list:
        """SQLAlchemy conditions on a time ``column``."""
        out = []
        if self.start is not None:
            out.append(column >= self.start)
        if self.end is not None:
            out.append(column <= self.end)
        return out

    def words(self) -> str:
        if self.start is None and self.end is None:
            return "the whole stored history"
        return f"{iso_z(self.start) if self.start else 'the first operation'} to " \
               f"{iso_z(self.end) if self.end else 'the latest operation'}"
