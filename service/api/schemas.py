"""Request and response schemas: one family per entity (Create / Update / Public)."""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, PlainSerializer, RootModel, WithJsonSchema

from .schemas_record import MaskedSpan, OperationEvents, RecordedChannel, UploadedOperation


def iso_z(t: datetime | None) -> str | None:
    if t is None:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=timezone.utc)
    return t.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")


# documented as what it is, an RFC 3339 time (a generated client parses it into a datetime)
UtcTime = Annotated[datetime, PlainSerializer(iso_z, return_type=str, when_used="json"),
                    WithJsonSchema({"type": "string", "format": "date-time"})]


def _no_paths(text: str | None) -> str | None:
    from service.errors import redact_paths

    return redact_paths(text)


# A failure reason as answered: absolute server paths cut to file names (D11, docs/security.md)
Reason = Annotated[str | None, PlainSerializer(_no_paths, return_type=str | None)]

UNITS = {"AO": "s^-2", "BO": "s^-2", "DO": "s^-1", "EO": "s^-2", "AC": "s^-2", "BC": "1", "CC": "s^-2",
         "DC": "s^-2"}
OPENING = ("AO", "BO", "DO", "EO")
CLOSING = ("AC", "BC", "CC")
ParameterName = Literal["AO", "BO", "DO", "EO", "AC", "BC", "CC"]
Role = Literal["agent", "reader", "operator", "admin"]


class ORM(BaseModel):
    model_config = ConfigDict(from_attributes=True)


# -- breakers ----------------------------------------------------------------------------------
class BreakerCreate(BaseModel):
    """A breaker file (TOML text) and its cam table (CSV text), as in config/breakers/."""

    breaker_file: str = Field(min_length=1, max_length=200_000)
    cam_table: str = Field(min_length=1, max_length=5_000_000, description="camshaft angle -> output-shaft angle, "
                           "two columns; every design needs one")
    tag: str | None = Field(None, max_length=60, pattern=r"^[A-Za-z0-9_\-]+$",
                            description="SCADA designation used in point names, e.g. Q1")


class BreakerPublic(ORM):
    id: int
    name: str
    tag: str
    created_at: UtcTime
    updated_at: UtcTime
    baseline_reset_at: UtcTime | None = None


class BreakerDetail(BreakerPublic):
    breaker_file: str
    cam_file_name: str
    design_parameters: dict[str, float]


# -- fits and operations -----------------------------------------------------------------------
class FitPublic(ORM):
    status: Literal["queued", "running", "done", "failed"]
    attempts: int
    failure_reason: Reason = None
    parameters: dict[str, float] | None = None
    ci95: dict[str, list[float]] | None = None
    stderr: dict[str, float] | None = None
    rmse_rad: float | None = None
    window_start_s: float | None = None
    window_end_s: float | None = None
    onset_delay_s: float | None = None
    evaluations: int | None = None
    runtime_s: float | None = None
    identifiable: bool | None = None
    condition_number: float | None = None
    dc_used: float | None = None
    dc_source: str | None = None
    warnings: list[str] | None = None
    characteristics: dict | None = None
    interval_noise: dict | None = Field(None, description="which noise the 95 % intervals and the residual band "
                                        "stand for: basis \"idle samples\" or \"residual in motion\" (HAC "
                                        "sandwich of the residual less its smooth, repeating part, "
                                        "docs/estimation.md), band_rad its 1σ [rad], each parameter's "
                                        "widening over the idle-noise interval")
    model_bias: dict | None = Field(None, description="the residual the breaker repeats, not in the intervals: "
                                    "basis (the breaker's recent mean residual, or this operation's smooth part), "
                                    "rms_rad [rad], rms_over_noise, and effect_bound: each parameter's largest "
                                    "shift a misfit of that size could cause [parameter unit]")
    zero_rad: float | None = Field(None, description="the transducer's zero before the motion, taken off before "
                                   "the fit [rad]")
    queued_at: UtcTime
    started_at: UtcTime | None = None
    finished_at: UtcTime | None = None


class OperationPublic(ORM):
    id: int
    breaker_id: int
    kind: Literal["open", "close"]
    occurred_at: UtcTime
    received_at: UtcTime
    source: str
    capture_sha256: str
    flags: list[str]
    sample_rate: float
    n_samples: int
    clock_suspect: bool = Field(False, description="dated more than clock_tolerance_s after it arrived: "
                                "not latest, not on SCADA, not in the drift baseline")
    temperature_c: float | None = Field(None, description="temperature of the operation [C] (docs/alarms.md)")
    temperature_source: str | None = Field(None, description="channel | upload | agent | scada")
    fit: FitPublic | None = None
    masked_samples: list[MaskedSpan] = Field(
        default_factory=list, description="samples the recorder marked over-range (∞, NaN), per channel and "
                                          "span: missing, not measured (GET /operations/{id} only)")


class CurvePublic(BaseModel):
    operation_id: int
    kind: str
    t_s: list[float] = Field(description="time from the first sample [s]")
    measured_rad: list[float] = Field(description="measured travel from the closed position [rad]")
    fitted_rad: list[float | None] | None = Field(None, description="fitted travel [rad]; null before the fit")
    residual_rad: list[float | None] | None = Field(None, description="measured − fitted [rad]")
    window_s: list[float] | None = None
    channels: dict[str, RecordedChannel] = Field(
        default_factory=dict, description="every other recorded channel (an analyser's coil currents, DCRM) "
                                          "in its own unit; t_s is then the min/max decimation of them all")
    events: OperationEvents | None = Field(None, description="command and contact instants (analyser records)")


class UploadAccepted(BaseModel):
    operation_id: int | None = Field(description="null when the database is unavailable: the capture is "
                                                 "spooled and will be stored after recovery")
    capture_key: str
    operation: Literal["open", "close"]
    status: Literal["queued", "spooled", "duplicate"] = Field(
        description="duplicate: a capture with this Idempotency-Key was stored before; this is its operation")
    operations: list[UploadedOperation] = Field(
        default_factory=list, description="every operation stored from the upload, in the record's order "
                                          "(a close-open analyser record: its closing and its opening)")


# -- health and trends -------------------------------------------------------------------------
class ParameterEstimate(BaseModel):
    value: float
    unit: str
    ci95: list[float] | None = None
    time: UtcTime
    operation_id: int
    identifiable: bool = True


class LatestFit(BaseModel):
    operation_id: int
    time: UtcTime
    rmse_rad: float | None = None
    identifiable: bool | None = None
    parameters: dict[str, ParameterEstimate]
    characteristics: dict | None = None


class AlarmPublic(ORM):
    id: int
    breaker_id: int
    parameter: str
    level: Literal["warning", "alarm"]
    state: Literal["raised", "acknowledged", "cleared"]
    message: str
    evidence: dict
    operation_id: int | None = None
    raised_at: UtcTime
    updated_at: UtcTime
    acknowledged_at: UtcTime | None = None
    acknowledged_by: str | None = None
    ack_comment: str | None = None
    cleared_at: UtcTime | None = None


class AlarmAck(BaseModel):
    comment: str | None = Field(None, max_length=2000)


class HealthPublic(BaseModel):
    breaker_id: int
    status: Literal["ok", "warning", "alarm", "unknown"]
    opening: LatestFit | None = None
    closing: LatestFit | None = None
    characteristics: dict = Field(default_factory=dict, description="travel characteristics by operation")
    active_alarms: list[AlarmPublic]
    temperature_compensation: dict[str, str] = Field(
        default_factory=dict, description='per watched parameter: "temperature-compensated" or '
                                          '"not temperature-compensated" (docs/alarms.md)')


class TrendPoint(BaseModel):
    time: UtcTime
    value: float
    ci95: list[float] | None = None
    operation_id: int
    identifiable: bool


class TrendPublic(BaseModel):
    breaker_id: int
    name: str
    unit: str
    points: list[TrendPoint]


class ScadaPoint(BaseModel):
    point: str = Field(description="e.g. Q1.opening.DO")
    value: float | None
    unit: str
    timestamp: UtcTime | None
    quality: Literal["good", "uncertain", "bad"]
    shelved_until: UtcTime | None = Field(None, description="the parameter's active alarm is shelved "
                                          "until then (ISA-18.2): it is left out of alarm_level")
    shelved_by: str | None = Field(None, description="who shelved it")


class ScadaPointList(RootModel[list[ScadaPoint]]):
    pass


# -- keys --------------------------------------------------------------------------------------
class ApiKeyCreate(BaseModel):
    name: str = Field(min_length=1, max_length=120)
    role: Role


class ApiKeyPublic(ORM):
    id: int
    name: str
    prefix: str
    role: Role
    created_at: UtcTime
    revoked_at: UtcTime | None = None


class ApiKeyCreated(ApiKeyPublic):
    key: str = Field(description="shown once; only its hash is stored")


class BaselineReset(BaseModel):
    reason: str = Field("maintenance", max_length=500)


class DiagnosisPublic(BaseModel):
    operation_id: int
    status: str = Field(description="queued | running | done | failed")
    requested_at: datetime
    finished_at: datetime | None = None
    failure_reason: Reason = None
    result: dict | None = Field(None, description="the `hvcb diagnose --json` object: gap, candidates, verdict, ...")


class Message(BaseModel):
    detail: str


class FieldError(BaseModel):
    loc: list[str | int] = Field(description="where: the field's path, e.g. [\"cam_table\"] or [\"name\"]")
    msg: str = Field(description="what is wrong, in words")
    type: str = Field(description="the kind of error, e.g. missing, string_too_long")


class ErrorBody(BaseModel):
    """Every error's body (4xx and 5xx): ``detail`` in words; ``errors`` per field on a 422 from
    validation."""

    detail: str = Field(description="what is wrong and, where it helps, what to do instead")
    errors: list[FieldError] | None = Field(None, description="each invalid field (422 from validation only)")
