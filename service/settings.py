"""The service's settings: one pydantic-settings class.

Sources, highest first: keyword arguments, environment variables, the TOML file
(``config/default.toml`` or the file given to ``hvcb serve --config``), field defaults.

Environment variables: ``HVCB_DATA_DIR``, ``DATABASE_URL`` (or ``HVCB_DATABASE_URL``),
``HVCB_BROKER_URL`` and ``HVCB_<FIELD>`` for every other field.
"""

from __future__ import annotations

import contextvars
import functools
import json
import logging
from pathlib import Path
from typing import Literal

from pydantic import AliasChoices, BaseModel, Field, field_validator, model_validator
from pydantic_settings import (BaseSettings, PydanticBaseSettingsSource, SettingsConfigDict,
                               TomlConfigSettingsSource)

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_CONFIG = REPO_ROOT / "config" / "default.toml"

# Known weak secrets refused anywhere a key or password can be configured.
_WEAK = {"changethis", "changeme", "secret", "password", "admin", "postgres", "hvcb", "test"}

log = logging.getLogger("hvcb.settings")

_config_file: contextvars.ContextVar[Path | None] = contextvars.ContextVar("hvcb_config_file", default=None)


class SerialDaqSettings(BaseModel):
    """A streaming DAQ on a serial line, USB CDC or ``socket://host:port`` (docs/drivers.md)."""

    model_config = {"extra": "forbid"}
    url: str = Field("", description="/dev/ttyACM0, /dev/serial/by-id/..., or socket://host:port")
    baudrate: int = Field(6_000_000, gt=0, description="[bit/s]; ignored by USB CDC and sockets")
    reconnect_min_s: float = Field(0.1, gt=0)
    reconnect_max_s: float = Field(5.0, gt=0)


class ModbusDaqSettings(BaseModel):
    """A capture-buffer DAQ on Modbus TCP or RTU (docs/drivers.md, config/modbus-registers.toml)."""

    model_config = {"extra": "forbid"}
    transport: Literal["tcp", "rtu"] = "tcp"
    host: str = "127.0.0.1"
    port: int = Field(502, ge=1, le=65535)
    url: str = Field("", description="RTU: serial device or socket://gateway:port")
    baudrate: int = Field(115200, gt=0)
    device_id: int = Field(1, ge=0, le=247)
    timeout_s: float = Field(1.0, gt=0)
    poll_interval_s: float = Field(0.2, gt=0)
    block_retries: int = Field(3, ge=0)


class ReplayDaqSettings(BaseModel):
    """Recorded COMTRADE/CSV files played as if a DAQ sent them."""

    model_config = {"extra": "forbid"}
    files: list[Path] = Field(default_factory=list)
    speed: float | None = Field(1.0, gt=0, description="1 = real time; empty/None = as fast as possible")


class AcquisitionSettings(BaseModel):
    """One ``[[acquisition]]`` entry: a DAQ and the breaker it watches. Only the chosen driver's
    table is used. A driver that fails or whose stream ends is rebuilt after ``retry_min_s``,
    doubling up to ``retry_max_s`` (docs/deployment.md)."""

    model_config = {"extra": "forbid"}
    driver: Literal["none", "serial", "modbus", "replay"] = "none"
    breaker: str = Field("", description="breaker name (breaker file `name`); empty = the first configured")
    name: str = Field("", max_length=60, pattern=r"^[A-Za-z0-9_.:-]*$",
                      description="label of this DAQ in /healthz and /metrics; empty = the breaker name")
    status_interval_s: float = Field(1.0, gt=0, description="how often the driver counters are stored")
    retry_min_s: float = Field(1.0, gt=0, description="first wait before a failed driver is rebuilt [s]")
    retry_max_s: float = Field(60.0, gt=0, description="longest wait between rebuilds [s]")
    serial: SerialDaqSettings = Field(default_factory=SerialDaqSettings)
    modbus: ModbusDaqSettings = Field(default_factory=ModbusDaqSettings)
    replay: ReplayDaqSettings = Field(default_factory=ReplayDaqSettings)

    @model_validator(mode="after")
    def _complete(self):
        if self.driver == "serial" and not self.serial.url:
            raise ValueError("acquisition driver 'serial' needs serial.url (a device path or socket://host:port)")
        if self.driver == "modbus" and self.modbus.transport == "rtu" and not self.modbus.url:
            raise ValueError("acquisition driver 'modbus' with transport 'rtu' needs modbus.url")
        if self.driver == "replay" and not self.replay.files:
            raise ValueError("acquisition driver 'replay' needs replay.files")
        if self.retry_min_s > self.retry_max_s:
            raise ValueError("acquisition retry_min_s must not exceed retry_max_s")
        return self


class WebSettings(BaseModel):
    """``[web]``: the engineers' web page (service/web/)."""

    model_config = {"extra": "forbid"}
    session_hours: float = Field(8.0, gt=0, le=24 * 30, description="a sign-in lasts this long")
    secure_cookie: Literal["auto", "always", "never"] = Field(
        "auto", description="Secure flag of the session cookie; auto = when the request came over HTTPS")
    poll_s: float = Field(3.0, gt=0, le=300, description="how often open pages ask for news")
    secret: str = Field("", description="cookie signing key; empty = generated once into <data_dir>/web.secret")


class RetentionSettings(BaseModel):
    """``[retention]``: how long raw captures stay on disk (docs/operations.md). Fits, alarms and
    operation rows are kept forever, and so are the raw captures an alarm's evidence, a baseline
    or a developing drift names. Any other raw capture is pruned when it is older than
    ``max_age_days`` or not among its breaker's newest ``max_per_breaker``; a decimated preview
    stays for the web page. Both limits empty: nothing is pruned."""

    model_config = {"extra": "forbid"}
    max_age_days: float | None = Field(None, gt=0, description="prune raw captures older than this [days]")
    max_per_breaker: int | None = Field(None, ge=1, description="keep this many newest raw captures per breaker")
    interval_s: float = Field(3600.0, ge=0, description="how often the service prunes [s]; 0 = only `hvcb prune`")
    preview_buckets: int = Field(100, ge=10, le=2000, description="min/max buckets per channel in a preview")

    @field_validator("max_age_days", "max_per_breaker", mode="before")
    @classmethod
    def _off_when_empty(cls, v):
        return None if isinstance(v, str) and not v.strip() else v

    @property
    def active(self) -> bool:
        return self.max_age_days is not None or self.max_per_breaker is not None


class ServerSettings(BaseModel):
    """``[server]``: how much the service takes on at once, and how long it waits for a slow
    client (docs/security.md gives the reasons for each default)."""

    model_config = {"extra": "forbid"}
    threads: int = Field(16, ge=4, le=512, description="threads for request handlers (database pool = threads + 12)")
    max_active_requests: int = Field(8, ge=1, le=512, description="page and API reads served at once; "
                                     "must leave threads for /healthz, SCADA and key checks")
    max_queued_requests: int = Field(1000, ge=0, le=100_000, description="more reads wait in a queue; "
                                     "beyond it: 503 with Retry-After")
    queue_timeout_s: float = Field(60.0, gt=0, description="a read waits this long for its turn, then 503")
    max_request_bytes: int = Field(6 * 1024 * 1024, ge=1024, description="body limit of every request but uploads "
                                   "(a breaker file with a 5 MB cam table fits)")
    upload_parsers: int = Field(1, ge=1, le=16, description="uploads parsed at once (memory bound, docs/security.md)")
    header_timeout_s: float = Field(10.0, gt=0, description="a request's headers must arrive within this time")
    body_idle_timeout_s: float = Field(15.0, gt=0, description="longest pause between two pieces of a body")
    body_timeout_s: float = Field(300.0, gt=0, description="a whole body must arrive within this time")
    keepalive_s: int = Field(20, ge=1, le=300, description="an idle kept-alive connection is closed after this "
                             "(long enough that a busy client does not reuse a connection as it closes)")
    max_connections: int = Field(2048, ge=16, description="open connections and requests; beyond: 503")
    trusted_proxies: str = Field("127.0.0.1", description="addresses whose X-Forwarded-For is believed "
                                 "(the TLS reverse proxy); comma-separated")
    auth_free_failures: int = Field(5, ge=1, description="wrong keys or sign-ins an address gets before throttling")
    auth_delay_base_s: float = Field(0.5, gt=0, description="first throttling delay; doubles at each failure")
    auth_delay_max_s: float = Field(60.0, gt=0, description="longest throttling delay")
    auth_forget_s: float = Field(900.0, gt=0, description="an address without failures for this long starts afresh")
    report_wait_s: float = Field(8.0, ge=0, le=60, description="GET .../report waits this long for the worker's "
                                 "PDF, then answers 202 with the job (its URL gives the PDF when done)")
    sqlite_busy_s: float = Field(10.0, gt=0, le=120, description="SQLite: a write waits this long for another "
                                 "writer's lock before a bounded retry (docs/operations.md); WAL: reads never wait")

    @model_validator(mode="after")
    def _headroom(self):
        if self.max_active_requests > self.threads - 4:
            raise ValueError("[server] max_active_requests must leave at least 4 of the threads free "
                             "(for /healthz, SCADA and key checks)")
        return self

    @property
    def pool_size(self) -> int:
        """Database connections: one per handler thread plus the background threads (monitor,
        spool, DAQs, retention, trend warm-up, IEC 61850, diagnoses), so none waits for a connection."""
        return self.threads + 12


def acquisition_list(value, where: str = "settings"):
    """``[[acquisition]]`` (a list) as is; the old single ``[acquisition]`` table as a one-entry
    list, with a deprecation note. Entries with driver "none" are dropped."""
    if value is None:
        return []
    if isinstance(value, (dict, AcquisitionSettings)):
        log.warning("%s: the single [acquisition] table is deprecated; write [[acquisition]] "
                    "(one entry per DAQ, see docs/deployment.md)", where)
        value = [value]
    if not isinstance(value, (list, tuple)):
        raise ValueError("acquisition must be a list of [[acquisition]] tables")
    out = []
    for v in value:
        driver = v.driver if isinstance(v, AcquisitionSettings) else (v.get("driver", "none")
                                                                      if isinstance(v, dict) else None)
        if driver != "none":
            out.append(v)
    return out


def check_daq_list(daqs: list[AcquisitionSettings]) -> None:
    """Several DAQs need their breaker named, one DAQ per breaker, and distinct labels."""
    if len(daqs) > 1 and any(not d.breaker for d in daqs):
        raise ValueError("with several [[acquisition]] entries each needs its `breaker`")
    breakers = [d.breaker for d in daqs]
    if len(set(breakers)) != len(breakers):
        raise ValueError("two [[acquisition]] entries watch the same breaker; one DAQ per breaker")
    names = [d.name for d in daqs if d.name]
    if len(set(names)) != len(names):
        raise ValueError("two [[acquisition]] entries have the same name")


class Settings(BaseSettings):
    """Everything the service, its workers and its commands read."""

    model_config = SettingsConfigDict(env_prefix="HVCB_", extra="forbid", populate_by_name=True,
                                      env_nested_delimiter="__")

    data_dir: Path = Field(Path("var"), description="SQLite file, capture files, spool and generated key")
    database_url: str | None = Field(
        None, validation_alias=AliasChoices("database_url", "DATABASE_URL", "HVCB_DATABASE_URL"),
        description="SQLAlchemy URL; empty means SQLite at <data_dir>/hvcb.sqlite3")
    broker_url: str | None = Field(None, description="Celery broker (redis://...); empty means local process pool")
    executor: Literal["auto", "local", "celery", "inline"] = "auto"
    workers: int = Field(1, ge=1, le=64, description="local process-pool size")
    max_attempts: int = Field(3, ge=1, le=20, description="a job whose worker dies this often is failed")
    host: str = "127.0.0.1"
    port: int = Field(8000, ge=1, le=65535)
    breakers: list[Path] = Field(default_factory=list, description="breaker files registered at start")
    tags: dict[str, str] = Field(default_factory=dict, description="breaker name -> SCADA tag (e.g. Q1)")
    max_upload_bytes: int = Field(32 * 1024 * 1024, ge=1024)
    stale_after_s: float = Field(7 * 24 * 3600.0, gt=0, description="older parameters are quality bad")
    daq_timeout_s: float = Field(30.0, gt=0, description="no DAQ heartbeat for this long: DAQ down")
    spool_retry_s: float = Field(2.0, gt=0, description="how often spooled captures are retried")
    fit_lease_s: float = Field(300.0, ge=10, description="a fit `running` this long has lost its worker "
                               "and is queued again (a fit takes seconds; docs/operations.md)")
    fit_seed: int = 1
    fit_function: str = Field("service.estimation:fit_capture",
                              description="module:function used by fit jobs (tests inject failures here)")
    celery_visibility_timeout_s: int = Field(600, ge=10, description="Redis: an unacknowledged task whose "
                                             "worker machine vanished is redelivered after this long")
    celery_queue: str = Field("hvcb", min_length=1, max_length=100, pattern=r"^[A-Za-z0-9_.:-]+$",
                              description="Celery queue the fit tasks go to (API and workers must agree)")
    celery_key_prefix: str = Field("", max_length=100, pattern=r"^[A-Za-z0-9_.:-]*$",
                                   description="prefix of every Redis key (several installations, one Redis)")
    bootstrap_admin_key: str | None = Field(None, description="admin key created at first start; "
                                            "generated when empty")
    acquisition: list[AcquisitionSettings] = Field(
        default_factory=list, description="the DAQs this service listens to ([[acquisition]], one per DAQ; "
                                          "the old single [acquisition] table is still read)")
    web: WebSettings = Field(default_factory=WebSettings, description="the web page ([web] table)")
    server: ServerSettings = Field(default_factory=ServerSettings, description="limits and timeouts ([server] table)")
    clock_tolerance_s: float = Field(86400.0, gt=0, description="a capture dated more than this after its arrival "
                                     "is flagged clock suspect (docs/security.md)")
    retention: RetentionSettings = Field(default_factory=RetentionSettings,
                                         description="raw-capture retention ([retention] table)")
    alarms: dict = Field(default_factory=dict, description="drift detector settings, see docs/alarms.md "
                         "(service.alarms.settings.DriftSettings; checked, and the thresholds designed, "
                         "when first used: the service does so at start)")
    notifications: dict = Field(
        default_factory=dict,
        description="where alarm and prognosis events are sent ([notifications], docs/notifications.md); "
                    "the notifications read their own section (service.notifications.routes), at start")
    iec61850_port: int | None = Field(None, ge=1, le=65535,
                                      description="IEC 61850 (MMS) server port; empty = off (102 is the "
                                      "standard port and needs privileges), see docs/iec61850.md")

    @field_validator("iec61850_port", mode="before")
    @classmethod
    def _port_off_when_empty(cls, v):
        return None if isinstance(v, str) and not v.strip() else v

    @classmethod
    def settings_customise_sources(cls, settings_cls: type[BaseSettings],
                                   init_settings: PydanticBaseSettingsSource,
                                   env_settings: PydanticBaseSettingsSource,
                                   dotenv_settings: PydanticBaseSettingsSource,
                                   file_secret_settings: PydanticBaseSettingsSource):
        path = _config_file.get() or DEFAULT_CONFIG
        sources = [init_settings, env_settings]
        if path.is_file():
            sources.append(TomlSource(settings_cls, toml_file=path))
        return tuple(sources)

    @field_validator("bootstrap_admin_key")
    @classmethod
    def _strong_key(cls, v):
        if v is None or v == "":
            return None
        if len(v) < 24 or v.lower() in _WEAK:
            raise ValueError("bootstrap_admin_key must be at least 24 random characters; "
                             "leave it empty to have one generated")
        return v

    @field_validator("acquisition", mode="before")
    @classmethod
    def _acquisition_list(cls, v):
        return acquisition_list(v)

    @field_validator("acquisition")
    @classmethod
    def _daq_list(cls, v):
        check_daq_list(v)
        return v

    @field_validator("database_url")
    @classmethod
    def _no_default_password(cls, v):
        if not v:
            return None
        from sqlalchemy.engine import make_url
        try:
            url = make_url(v)
        except Exception:
            raise ValueError(f"database_url is not a valid SQLAlchemy URL: {v!r}") from None
        if url.password and url.password.lower() in _WEAK:
            raise ValueError("database_url uses a well-known default password; set a real one")
        if url.drivername == "postgresql" or url.drivername == "postgres":
            url = url.set(drivername="postgresql+psycopg")
            return url.render_as_string(hide_password=False)
        return v

    @model_validator(mode="after")
    def _resolve(self):
        if self.executor == "celery" and not self.broker_url:
            raise ValueError("executor 'celery' needs broker_url (HVCB_BROKER_URL)")
        return self

    # -- derived ------------------------------------------------------------------------------
    @property
    def sqlalchemy_url(self) -> str:
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'hvcb.sqlite3').resolve()}"

    @property
    def executor_kind(self) -> str:
        if self.executor != "auto":
            return self.executor
        return "celery" if self.broker_url else "local"

    @property
    def drift_settings(self):
        """The drift detector's settings (``[alarms]``), built and their CUSUM thresholds designed
        on first use, once per distinct section (loading the settings designs nothing: a command
        that needs no alarms never pays for it). Bad values raise ValueError in words."""
        return drift_settings_for(self.alarms)

    @property
    def capture_dir(self) -> Path:
        return self.data_dir / "captures"

    @property
    def spool_dir(self) -> Path:
        return self.data_dir / "spool"

    @property
    def key_file(self) -> Path:
        return self.data_dir / "admin.key"


def drift_settings_for(section: dict):
    """The drift detector's settings of an ``[alarms]`` section (a worker process given only the
    section), designed once per distinct section in this process."""
    return _drift_settings(json.dumps(section, sort_keys=True, default=str))


@functools.lru_cache(maxsize=16)
def _drift_settings(section_json: str):
    from service.alarms.settings import DriftSettings

    settings = DriftSettings.from_mapping(json.loads(section_json))
    settings.h_warning, settings.h_alarm  # designed here, once, for every later reader
    return settings


class TomlSource(TomlConfigSettingsSource):
    """TOML source whose relative breaker paths are resolved against the file's directory."""

    def __init__(self, settings_cls, toml_file: Path):
        super().__init__(settings_cls, toml_file=toml_file)
        base = Path(toml_file).resolve().parent
        data = self.toml_data if hasattr(self, "toml_data") else None
        for store in (data, getattr(self, "init_kwargs", None)):
            if isinstance(store, dict) and "breakers" in store:
                store["breakers"] = [str((base / p).resolve()) for p in store["breakers"]]


def load_settings(config_file: str | Path | None = None, **overrides) -> Settings:
    """Settings from ``config_file`` (default ``config/default.toml``), the environment and
    ``overrides``. Raises ``pydantic.ValidationError`` on bad or insecure values."""
    if config_file is not None:
        config_file = Path(config_file)
        if not config_file.is_file():
            raise FileNotFoundError(f"settings file not found: {config_file}")
    token = _config_file.set(config_file)
    try:
        return Settings(**overrides)
    finally:
        _config_file.reset(token)


def command_settings(args, **overrides) -> Settings:
    """The settings of an ``hvcb`` subcommand: its ``--config`` file (if any) and the ``overrides``
    that are not None. Bad values raise ``UserError`` that lists each field and what is wrong."""
    from pydantic import ValidationError

    from service.errors import UserError

    overrides = {k: v for k, v in overrides.items() if v is not None}
    try:
        return load_settings(getattr(args, "config", None), **overrides)
    except ValidationError as exc:
        raise UserError("bad settings: " + "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}"
                                                     for e in exc.errors())) from None
