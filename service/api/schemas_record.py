"""Response models of a recorded analyser record: the operations one upload stored, and the
recorded channels and marked instants served beside an operation's travel curve."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field


class UploadedOperation(BaseModel):
    operation_id: int | None = Field(description="null when the database is unavailable (spooled)")
    capture_key: str
    operation: Literal["open", "close"]


class RecordedChannel(BaseModel):
    kind: str = Field(description="coil_current, travel (as recorded), resistance (DCRM) or dcrm_current")
    unit: str = Field(description="A for coil and DCRM currents, mm for a recorded travel, µΩ for the DCRM")
    values: list[float] = Field(description="at the curve's t_s")


class OperationEvents(BaseModel):
    command_s: float | None = Field(None, description="coil command instant [s from the first sample]")
    command_source: str | None = None
    contact_event: str = Field(description="'contact part' (opening) or 'contact touch' (closing)")
    contact_s: float | None = Field(None, description="[s from the first sample]")
    contact_source: str | None = Field(None, description="the DCRM step, else the travel's contact point")


class MaskedSpan(BaseModel):
    """A run of samples the recorder marked over-range (∞, NaN, OL): missing, not measured."""

    channel: str = Field(description="the record's channel name (T1, C4, R1 ...)")
    first_s: float = Field(description="first masked sample [s from the operation's first sample]")
    last_s: float = Field(description="last masked sample [s from the operation's first sample]")
    count: int = Field(description="masked samples in the span")
