"""SQLAlchemy 2 models. The schema itself is created by Alembic (``migrations/``), never here."""

from __future__ import annotations

from datetime import datetime, timezone

from sqlalchemy import (JSON, BigInteger, Boolean, DateTime, Float, ForeignKey, Index, Integer, String, Text,
                        TypeDecorator, UniqueConstraint, false, true)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship


def utcnow() -> datetime:
    return datetime.now(timezone.utc)


class UtcDateTime(TypeDecorator):
    """Timezone-aware UTC datetimes on every backend (SQLite stores them naive)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value, dialect):
        if value is None:
            return None
        if value.tzinfo is None:
            value = value.replace(tzinfo=timezone.utc)
        value = value.astimezone(timezone.utc)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value, dialect):
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=timezone.utc)
        return value.astimezone(timezone.utc)


class Base(DeclarativeBase):
    type_annotation_map = {datetime: UtcDateTime, dict: JSON, list: JSON}


FIT_STATUSES = ("queued", "running", "done", "failed")
ALARM_STATES = ("raised", "acknowledged", "cleared")
ROLES = ("agent", "reader", "operator", "admin")


class BreakerRow(Base):
    """One monitored breaker with its breaker file and cam table as they were registered."""

    __tablename__ = "breakers"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(120), unique=True)
    tag: Mapped[str] = mapped_column(String(60), unique=True)
    breaker_file: Mapped[str] = mapped_column(Text)
    cam_file_name: Mapped[str] = mapped_column(String(255))
    cam_table: Mapped[str] = mapped_column(Text)
    content_sha256: Mapped[str] = mapped_column(String(64))
    baseline_reset_at: Mapped[datetime | None]
    # Latest temperature SCADA wrote (PUT /api/v1/breakers/{name}/temperature) [C]; it applies
    # to operations that carry none of their own.
    scada_temperature_c: Mapped[float | None] = mapped_column(Float)
    scada_temperature_at: Mapped[datetime | None]
    # Out of service (maintenance): fits are not fed to the drift detector; the baseline is
    # reset when the breaker returns to service.
    out_of_service_since: Mapped[datetime | None]
    out_of_service_by: Mapped[str | None] = mapped_column(String(120))
    out_of_service_reason: Mapped[str | None] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)


class OperationRow(Base):
    """One breaker operation and its durable capture file."""

    __tablename__ = "operations"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), index=True)
    kind: Mapped[str] = mapped_column(String(8))  # open | close
    capture_key: Mapped[str] = mapped_column(String(64), unique=True)  # spool key: idempotent ingest
    occurred_at: Mapped[datetime]
    received_at: Mapped[datetime] = mapped_column(default=utcnow)
    source: Mapped[str] = mapped_column(String(40))  # daq | upload | replay
    capture_path: Mapped[str] = mapped_column(String(1024))
    capture_sha256: Mapped[str] = mapped_column(String(64))
    flags: Mapped[list] = mapped_column(default=list)
    sample_rate: Mapped[float] = mapped_column(Float)
    n_samples: Mapped[int] = mapped_column(Integer)
    # dated more than [clock_tolerance_s] after it arrived: kept and shown, but never "latest",
    # never on SCADA and never in the drift baseline (migration 0006)
    clock_suspect: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false(), index=True)
    temperature_c: Mapped[float | None] = mapped_column(Float)  # ambient/mechanism [C]
    temperature_source: Mapped[str | None] = mapped_column(String(16))  # channel|upload|agent|scada
    fit: Mapped[FitRow | None] = relationship(back_populates="operation", uselist=False, lazy="selectin")

    __table_args__ = (Index("ix_operations_breaker_time", "breaker_id", "occurred_at"),)


class FitRow(Base):
    """The fit job of one operation, and its result. One row per operation: the job key."""

    __tablename__ = "fits"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    operation_id: Mapped[int] = mapped_column(ForeignKey("operations.id", ondelete="CASCADE"), unique=True)
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), index=True)
    kind: Mapped[str] = mapped_column(String(8))
    status: Mapped[str] = mapped_column(String(10), default="queued", index=True)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    results_stored: Mapped[int] = mapped_column(Integer, default=0)  # must never exceed 1
    failure_reason: Mapped[str | None] = mapped_column(Text)
    parameters: Mapped[dict | None]
    ci95: Mapped[dict | None]
    stderr: Mapped[dict | None]
    rmse_rad: Mapped[float | None] = mapped_column(Float)
    fitness: Mapped[float | None] = mapped_column(Float)
    window_start_s: Mapped[float | None] = mapped_column(Float)
    window_end_s: Mapped[float | None] = mapped_column(Float)
    onset_delay_s: Mapped[float | None] = mapped_column(Float)
    noise_rad: Mapped[float | None] = mapped_column(Float)
    evaluations: Mapped[int | None] = mapped_column(Integer)
    runtime_s: Mapped[float | None] = mapped_column(Float)
    identifiable: Mapped[bool | None] = mapped_column(Boolean)
    condition_number: Mapped[float | None] = mapped_column(Float)
    dc_used: Mapped[float | None] = mapped_column(Float)
    dc_source: Mapped[str | None] = mapped_column(String(120))
    warnings: Mapped[list | None]
    characteristics: Mapped[dict | None]
    curve: Mapped[dict | None]  # {"t": [...], "fitted": [...]} downsampled fitted travel [s, rad]
    result: Mapped[dict | None]  # FitResult.to_dict(), for completeness
    worker: Mapped[str | None] = mapped_column(String(120))
    queued_at: Mapped[datetime] = mapped_column(default=utcnow)
    started_at: Mapped[datetime | None]
    finished_at: Mapped[datetime | None]
    # Refits: the row always holds the newest result; earlier ones move to fit_versions.
    version: Mapped[int] = mapped_column(Integer, default=1, server_default="1")
    refit_run_id: Mapped[int | None] = mapped_column(ForeignKey("refit_runs.id", ondelete="SET NULL"))
    operation: Mapped[OperationRow] = relationship(back_populates="fit")

    @property
    def interval_noise(self) -> dict | None:
        """Which noise the intervals and the residual band stand for (FitResult.interval_noise);
        None for a fit stored before it was recorded (its band is the idle samples' σ)."""
        return (self.result or {}).get("interval_noise")

    @property
    def model_bias(self) -> dict | None:
        """The residual the fit repeats, apart from its interval (FitResult.model_bias); None for
        a fit stored before it was recorded."""
        return (self.result or {}).get("model_bias")

    @property
    def zero_rad(self) -> float | None:
        """The transducer's zero the fit took off (FitResult.zero_rad) [rad]."""
        return (self.result or {}).get("zero_rad")


class DiagnosisRow(Base):
    """The sim-to-real gap diagnosis of one operation, computed on demand (one per operation)."""

    __tablename__ = "diagnoses"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    operation_id: Mapped[int] = mapped_column(ForeignKey("operations.id", ondelete="CASCADE"), unique=True)
    status: Mapped[str] = mapped_column(String(10), default="queued")  # queued | running | done | failed
    result: Mapped[dict | None]
    failure_reason: Mapped[str | None] = mapped_column(Text)
    requested_at: Mapped[datetime] = mapped_column(default=utcnow)
    finished_at: Mapped[datetime | None]


class ParameterValueRow(Base):
    """One fitted parameter of one operation: the trend and SCADA tables read these."""

    __tablename__ = "parameter_values"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    fit_id: Mapped[int] = mapped_column(ForeignKey("fits.id", ondelete="CASCADE"), index=True)
    operation_id: Mapped[int] = mapped_column(ForeignKey("operations.id", ondelete="CASCADE"))
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(String(8))
    name: Mapped[str] = mapped_column(String(16))
    value: Mapped[float] = mapped_column(Float)
    ci_low: Mapped[float | None] = mapped_column(Float)
    ci_high: Mapped[float | None] = mapped_column(Float)
    identifiable: Mapped[bool] = mapped_column(Boolean, default=True)
    occurred_at: Mapped[datetime]

    __table_args__ = (UniqueConstraint("fit_id", "name"),
                      Index("ix_parameter_values_trend", "breaker_id", "name", "occurred_at"))


class AlarmRow(Base):
    """A drift alarm and its lifecycle raised → acknowledged → cleared."""

    __tablename__ = "alarms"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), index=True)
    parameter: Mapped[str] = mapped_column(String(16))
    level: Mapped[str] = mapped_column(String(10))  # warning | alarm
    episode: Mapped[int] = mapped_column(Integer, default=0)  # the drift detector's alarm number
    state: Mapped[str] = mapped_column(String(14), default="raised", index=True)
    message: Mapped[str] = mapped_column(Text, default="")
    evidence: Mapped[dict] = mapped_column(default=dict)
    operation_id: Mapped[int | None] = mapped_column(ForeignKey("operations.id", ondelete="SET NULL"))
    raised_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)
    acknowledged_at: Mapped[datetime | None]
    acknowledged_by: Mapped[str | None] = mapped_column(String(120))
    ack_comment: Mapped[str | None] = mapped_column(Text)
    cleared_at: Mapped[datetime | None]
    # First-out (ISA-18.2): raised while no other alarm of the breaker was active.
    first_out: Mapped[bool] = mapped_column(Boolean, default=True, server_default=true())
    shelved_until: Mapped[datetime | None]
    shelved_at: Mapped[datetime | None]
    shelved_by: Mapped[str | None] = mapped_column(String(120))
    shelve_reason: Mapped[str | None] = mapped_column(Text)


class AlarmActionRow(Base):
    """Audit trail of what people did to alarms and breakers: who, when, why."""

    __tablename__ = "alarm_actions"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"))
    alarm_id: Mapped[int | None] = mapped_column(ForeignKey("alarms.id", ondelete="CASCADE"))
    action: Mapped[str] = mapped_column(String(24))
    by: Mapped[str] = mapped_column(String(120))
    at: Mapped[datetime] = mapped_column(default=utcnow)
    reason: Mapped[str] = mapped_column(Text, default="")
    until: Mapped[datetime | None]

    __table_args__ = (Index("ix_alarm_actions_breaker", "breaker_id", "at"),)


class DriftStateRow(Base):
    """The drift detector's persisted state for one watched parameter of one breaker."""

    __tablename__ = "drift_states"
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), primary_key=True)
    parameter: Mapped[str] = mapped_column(String(16), primary_key=True)
    state: Mapped[dict] = mapped_column(default=dict)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)


class PrognosisRow(Base):
    """The latest prognosis of one limited parameter of one breaker (service.prognosis), updated
    by the worker as each fit lands. ``median_operations`` is the median operations to the
    limit, None when no crossing is expected within the horizon (for SCADA and the fleet)."""

    __tablename__ = "prognoses"
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), primary_key=True)
    parameter: Mapped[str] = mapped_column(String(16), primary_key=True)
    median_operations: Mapped[float | None] = mapped_column(Float)
    result: Mapped[dict] = mapped_column(default=dict)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)


class SpringReferenceRow(Base):
    """A breaker's commissioning pair: a closing and an opening recorded at a known nut setting.
    The newest row is the reference its pairs' settings are read against (docs/pairs.md);
    ``reading`` is the pair's own reading then (steps, sd, friction from the design seat)."""

    __tablename__ = "spring_references"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), index=True)
    opening_id: Mapped[int] = mapped_column(ForeignKey("operations.id", ondelete="CASCADE"))
    closing_id: Mapped[int] = mapped_column(ForeignKey("operations.id", ondelete="CASCADE"))
    known_steps: Mapped[float] = mapped_column(Float)
    reading: Mapped[dict] = mapped_column(default=dict)
    recorded_by: Mapped[str] = mapped_column(String(200))
    recorded_at: Mapped[datetime] = mapped_column(default=utcnow)


class MaintenanceEventRow(Base):
    """One entry of the engineer's maintenance log (issue 50, docs/alarms.md "Maintenance log"):
    ``kind`` (service.alarms.maintenance.KINDS), when it was done and by whom, and the
    parameters it touches: their baseline, alarms and prognosis restart at ``done_at``."""

    __tablename__ = "maintenance_events"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), index=True)
    kind: Mapped[str] = mapped_column(String(64))
    done_at: Mapped[datetime]
    done_by: Mapped[str] = mapped_column(String(200))
    note: Mapped[str] = mapped_column(String(500), default="")
    parameters: Mapped[list] = mapped_column(default=list)
    recorded_by: Mapped[str] = mapped_column(String(200))
    recorded_at: Mapped[datetime] = mapped_column(default=utcnow)


class ApiKeyRow(Base):
    """An API key: only its SHA-256 is stored (keys are 256-bit random, so a fast hash is enough)."""

    __tablename__ = "api_keys"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(120))
    prefix: Mapped[str] = mapped_column(String(16))
    key_hash: Mapped[str] = mapped_column(String(64), unique=True)
    role: Mapped[str] = mapped_column(String(10))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    revoked_at: Mapped[datetime | None]


class DaqStatusRow(Base):
    """What the acquisition side last reported for a breaker's DAQ (for /healthz, SCADA, metrics)."""

    __tablename__ = "daq_status"
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"), primary_key=True)
    connected: Mapped[bool] = mapped_column(Boolean, default=False)
    last_seen: Mapped[datetime | None]
    frames: Mapped[int] = mapped_column(Integer, default=0)
    frames_dropped: Mapped[int] = mapped_column(Integer, default=0)
    crc_errors: Mapped[int] = mapped_column(Integer, default=0)
    captures: Mapped[int] = mapped_column(Integer, default=0)
    detail: Mapped[str] = mapped_column(Text, default="")


class WebSessionRow(Base):
    """A signed-in web session: the cookie carries the token, only its SHA-256 is stored."""

    __tablename__ = "web_sessions"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    key_id: Mapped[int] = mapped_column(ForeignKey("api_keys.id", ondelete="CASCADE"))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    expires_at: Mapped[datetime]
    ended_at: Mapped[datetime | None]


class RefitRunRow(Base):
    """One ``hvcb refit`` run: which operations, how far it got. Resumable by its id."""

    __tablename__ = "refit_runs"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    breaker_id: Mapped[int | None] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"))
    since: Mapped[datetime | None]
    status: Mapped[str] = mapped_column(String(12), default="queued")  # queued running interrupted done
    reason: Mapped[str | None] = mapped_column(Text)
    requested_by: Mapped[str | None] = mapped_column(String(120))
    total: Mapped[int] = mapped_column(Integer, default=0)
    done: Mapped[int] = mapped_column(Integer, default=0)
    failed: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    started_at: Mapped[datetime | None]
    finished_at: Mapped[datetime | None]


class FitVersionRow(Base):
    """A superseded result of an operation's fit (the fits row holds the newest version)."""

    __tablename__ = "fit_versions"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    fit_id: Mapped[int] = mapped_column(ForeignKey("fits.id", ondelete="CASCADE"))
    operation_id: Mapped[int] = mapped_column(ForeignKey("operations.id", ondelete="CASCADE"))
    version: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(10))
    failure_reason: Mapped[str | None] = mapped_column(Text)
    parameters: Mapped[dict | None]
    ci95: Mapped[dict | None]
    rmse_rad: Mapped[float | None] = mapped_column(Float)
    result: Mapped[dict | None]
    finished_at: Mapped[datetime | None]
    superseded_at: Mapped[datetime] = mapped_column(default=utcnow)
    superseded_by_run: Mapped[int | None] = mapped_column(ForeignKey("refit_runs.id", ondelete="SET NULL"))

    __table_args__ = (UniqueConstraint("operation_id", "version", name="uq_fit_versions_operation_version"),)


class CapturePreviewRow(Base):
    """What is left of a raw capture the retention policy removed: a decimated preview (min/max
    per bucket, so no peak vanishes) for the operation page. Its fit and alarms are untouched."""

    __tablename__ = "capture_previews"
    operation_id: Mapped[int] = mapped_column(ForeignKey("operations.id", ondelete="CASCADE"), primary_key=True)
    pruned_at: Mapped[datetime] = mapped_column(default=utcnow)
    bytes_freed: Mapped[int] = mapped_column(BigInteger, default=0)
    preview: Mapped[dict] = mapped_column(default=dict)  # {"t": [s], "travel": [rad], "vibration": [g] | None}


class BreakerDiagnosisRow(Base):
    """A gap diagnosis of a breaker's last N stored operations of one kind (issue 20).

    ``dedupe_key`` is the selection's key (breaker, operation, the operation ids) while the row
    is queued, running or done, and NULL once it failed: an identical request finds the row by
    this unique column instead of queuing a second job, and a failed one may be asked again.
    """

    __tablename__ = "breaker_diagnoses"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"))
    operation: Mapped[str] = mapped_column(String(8))  # open | close
    last_n: Mapped[int] = mapped_column(Integer)  # N asked for
    operation_ids: Mapped[list] = mapped_column(default=list)  # the operations diagnosed, oldest first
    skipped: Mapped[list] = mapped_column(default=list)  # [{"operation_id", "reason"}] left out
    selection_key: Mapped[str] = mapped_column(String(64))
    dedupe_key: Mapped[str | None] = mapped_column(String(64))
    status: Mapped[str] = mapped_column(String(10), default="queued", index=True)  # queued running done failed
    result: Mapped[dict | None]
    failure_reason: Mapped[str | None] = mapped_column(Text)
    requested_by: Mapped[str | None] = mapped_column(String(120))
    requested_key_id: Mapped[int | None] = mapped_column(ForeignKey("api_keys.id", ondelete="SET NULL"))
    requested_role: Mapped[str] = mapped_column(String(10))
    requested_at: Mapped[datetime] = mapped_column(default=utcnow)
    started_at: Mapped[datetime | None]
    finished_at: Mapped[datetime | None]

    __table_args__ = (Index("ix_breaker_diagnoses_breaker", "breaker_id", "id"),
                      UniqueConstraint("dedupe_key", name="uq_breaker_diagnoses_dedupe_key"))
