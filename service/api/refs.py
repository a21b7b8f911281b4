"""The API's edge, one way everywhere (issue 44 item 5): every ``/breakers/{…}`` route takes the
breaker's id, its name or its SCADA tag, resolved here; a date-time is an ISO 8601 string, never a
number."""

from __future__ import annotations

from typing import Annotated

from fastapi import HTTPException, Path as PathParam
from pydantic import BeforeValidator
from sqlalchemy import or_, select

from service.storage.models import BreakerRow

# Row ids are 32-bit on PostgreSQL: a larger number is a name, never a database error.
MAX_ID = 2_147_483_647
BreakerRef = Annotated[str, PathParam(min_length=1, max_length=120, description="breaker id, name or tag")]


def breaker_by_ref(session, ref: str) -> BreakerRow:
    """The breaker whose name or tag is ``ref``, else whose id it is; 404 in words when none is."""
    b = session.scalar(select(BreakerRow).where(or_(BreakerRow.name == ref, BreakerRow.tag == ref)))
    if b is None and ref.isascii() and ref.isdigit() and 1 <= int(ref) <= MAX_ID:  # not "¹": isdigit, no int
        b = session.get(BreakerRow, int(ref))
    if b is None:
        raise HTTPException(404, f"no breaker named {ref!r} (give its id, name or tag)")
    return b


def iso_only(v):
    """The schema says an ISO 8601 date-time: a bare number (pydantic's Unix time) is refused."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        raise ValueError("an ISO 8601 date-time is expected (e.g. 2026-11-28T08:00:00Z), not a number")
    if isinstance(v, str):
        try:
            float(v)
        except ValueError:
            return v
        raise ValueError("an ISO 8601 date-time is expected (e.g. 2026-11-28T08:00:00Z), not a number")
    return v


IsoOnly = BeforeValidator(iso_only)


def number_only(v):
    """The schema says a JSON number: true/false and strings are refused in words (pydantic's lax
    mode would read false as 0 and "3" as 3). An integer field still takes 3.0, which JSON Schema
    counts as an integer."""
    if isinstance(v, bool):
        raise ValueError(f"a number is expected, not {str(v).lower()}")
    if isinstance(v, (str, bytes)):
        raise ValueError(f"a number is expected, not the string {v!r}")
    return v


NumberOnly = BeforeValidator(number_only)
