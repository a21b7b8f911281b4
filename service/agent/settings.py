"""The edge agent's settings (``hvcb agent --config edge.toml``; config/edge.toml).

Sources, highest first: keyword arguments, ``HVCB_AGENT_<FIELD>`` environment variables (nested
with ``__``, e.g. ``HVCB_AGENT_CENTRAL__API_KEY``), the TOML file, field defaults.
"""

from __future__ import annotations

import contextvars
from pathlib import Path

from pydantic import BaseModel, Field, field_validator, model_validator
from pydantic_settings import BaseSettings, PydanticBaseSettingsSource, SettingsConfigDict

from service.settings import AcquisitionSettings, TomlSource, acquisition_list, check_daq_list

_agent_file: contextvars.ContextVar[Path | None] = contextvars.ContextVar("hvcb_agent_file", default=None)


class CentralSettings(BaseModel):
    """``[central]``: the hvcb the captures go to, through its upload API."""

    model_config = {"extra": "forbid"}
    url: str = Field(..., description="https://hvcb.example.net (the API behind its TLS proxy)")
    api_key: str = Field(..., description="a key of the `agent` role (hvcb key NAME --role agent)")
    breaker_ids: dict[str, int] = Field(..., description="breaker name -> its id on the central server")
    verify: bool | str = Field(True, description="TLS: true, false (tests only) or a CA bundle path")
    timeout_s: float = Field(30.0, gt=0)
    retry_min_s: float = Field(1.0, gt=0, description="first wait after a failed upload [s]")
    retry_max_s: float = Field(60.0, gt=0, description="longest wait between upload attempts [s]")

    @field_validator("url")
    @classmethod
    def _http(cls, v):
        if not v.startswith(("http://", "https://")):
            raise ValueError(f"central.url must start with https:// (or http:// on a trusted network), got {v!r}")
        return v.rstrip("/")

    @field_validator("api_key")
    @classmethod
    def _key(cls, v):
        if len(v) < 16:
            raise ValueError("central.api_key is empty or too short: create one on the central server with "
                             "`hvcb key NAME --role agent` (or set HVCB_AGENT_CENTRAL__API_KEY)")
        return v

    @model_validator(mode="after")
    def _order(self):
        if self.retry_min_s > self.retry_max_s:
            raise ValueError("central.retry_min_s must not exceed central.retry_max_s")
        return self


class AgentSettings(BaseSettings):
    """Everything ``hvcb agent`` reads."""

    model_config = SettingsConfigDict(env_prefix="HVCB_AGENT_", extra="forbid", env_nested_delimiter="__")

    data_dir: Path = Field(Path("var/agent"), description="capture files and the outbox")
    breakers: list[Path] = Field(default_factory=list, description="breaker files (trigger and scaling)")
    acquisition: list[AcquisitionSettings] = Field(default_factory=list, description="[[acquisition]], one per DAQ")
    central: CentralSettings
    spool_max_bytes: int = Field(2 * 1024 ** 3, ge=1024, description="outbox bound; when full, new captures "
                                 "are refused (oldest kept) with an error log and metric")
    metrics_host: str = "127.0.0.1"
    metrics_port: int = Field(0, ge=0, le=65535, description="Prometheus metrics port; 0 = off")

    @classmethod
    def settings_customise_sources(cls, settings_cls, init_settings: PydanticBaseSettingsSource,
                                   env_settings: PydanticBaseSettingsSource, dotenv_settings, file_secret_settings):
        path = _agent_file.get()
        sources = [init_settings, env_settings]
        if path is not None and path.is_file():
            sources.append(TomlSource(settings_cls, toml_file=path))
        return tuple(sources)

    @field_validator("acquisition", mode="before")
    @classmethod
    def _acquisition_list(cls, v):
        return acquisition_list(v, "agent settings")

    @model_validator(mode="after")
    def _complete(self):
        check_daq_list(self.acquisition)
        if not self.acquisition:
            raise ValueError("the agent needs at least one [[acquisition]] entry")
        if not self.breakers:
            raise ValueError("the agent needs its breaker files under `breakers`")
        return self

    @property
    def capture_dir(self) -> Path:
        return self.data_dir / "captures"

    @property
    def outbox_dir(self) -> Path:
        return self.data_dir / "outbox"


def load_agent_settings(config_file: str | Path | None = None, **overrides) -> AgentSettings:
    """Agent settings from ``config_file``, the environment and ``overrides``."""
    if config_file is not None:
        config_file = Path(config_file)
        if not config_file.is_file():
            raise FileNotFoundError(f"agent settings file not found: {config_file}")
    token = _agent_file.set(config_file)
    try:
        return AgentSettings(**overrides)
    finally:
        _agent_file.reset(token)
