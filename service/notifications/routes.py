"""Routes: where events go, and which ones (the ``[notifications]`` settings, docs/notifications.md).

A route has a kind (``webhook``, ``email`` or ``apprise``) and filters: breakers (names or SCADA
tags), parameters, severities and event kinds; an empty filter lets everything through. Secrets
may be given in the file or, better, named by an environment variable (``secret_env``,
``password_env``); they are read here, at the edge, once.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, Field, ValidationError, model_validator

from service.notifications.events import KINDS, SEVERITIES

# Known weak secrets refused (as service.settings refuses them for keys and passwords).
_WEAK = {"changethis", "changeme", "secret", "password", "admin", "hvcb", "test"}
# A webhook secret shorter than this is guessable offline from one signed body.
MIN_SECRET = 16

Kind = Literal["raised", "unshelved", "escalated", "acknowledged", "shelved", "cleared",
               "prognosis_entered", "prognosis_left"]


class RouteSettings(BaseModel):
    """One ``[[notifications.routes]]`` table."""

    model_config = {"extra": "forbid"}
    name: str = Field(..., min_length=1, max_length=60, pattern=r"^[A-Za-z0-9_.:-]+$")
    kind: Literal["webhook", "email", "apprise"]
    breakers: list[str] = Field(default_factory=list, description="breaker names or tags; empty = all")
    parameters: list[str] = Field(default_factory=list, description="e.g. DO, BO; empty = all")
    severities: list[Literal["warning", "alarm"]] = Field(default_factory=list, description="empty = all")
    events: list[Kind] = Field(default_factory=list, description="event kinds; empty = all")
    timeout_s: float = Field(10.0, gt=0, le=300, description="one attempt's time limit [s]")
    # webhook
    url: str = Field("", description="webhook: http(s)://... receiving the signed JSON")
    secret: str = Field("", repr=False, description="webhook: HMAC-SHA256 key")
    secret_env: str = Field("", description="webhook: environment variable holding the key")
    # email
    smtp_host: str = ""
    smtp_port: int = Field(587, ge=1, le=65535)
    starttls: bool = Field(True, description="upgrade the connection with STARTTLS before anything is sent")
    ca_file: Path | None = Field(None, description="CA certificates to trust instead of the system's")
    username: str = ""
    password: str = Field("", repr=False)
    password_env: str = Field("", description="environment variable holding the SMTP password")
    sender: str = Field("", description="From: address")
    to: list[str] = Field(default_factory=list, description="recipients")
    # apprise (chat services: Teams, Slack, Matrix, ntfy, ... one URL each)
    urls: list[str] = Field(default_factory=list, repr=False, description="apprise: service URLs")

    @model_validator(mode="after")
    def _complete(self):
        where = f"notification route {self.name!r}"
        if self.secret_env:
            self.secret = _from_env(self.secret_env, where)
        if self.password_env:
            self.password = _from_env(self.password_env, where)
        if self.kind == "webhook":
            if not self.url.startswith(("http://", "https://")):
                raise ValueError(f"{where}: a webhook needs url = \"http(s)://...\"")
            if len(self.secret) < MIN_SECRET or self.secret.lower() in _WEAK:
                raise ValueError(f"{where}: the webhook secret must be at least {MIN_SECRET} random characters "
                                 "(set secret_env to an environment variable holding it)")
        elif self.kind == "email":
            if not self.smtp_host or not self.sender or not self.to:
                raise ValueError(f"{where}: e-mail needs smtp_host, sender and to")
            if self.username and not self.starttls:
                raise ValueError(f"{where}: SMTP authentication needs starttls = true "
                                 "(a password is never sent in the clear)")
            if self.ca_file is not None and not self.ca_file.is_file():
                raise ValueError(f"{where}: ca_file {self.ca_file} not found")
        elif not self.urls:
            raise ValueError(f"{where}: apprise needs urls = [\"...\"] (see https://github.com/caronc/apprise/wiki)")
        return self

    def matches(self, *, kind: str, severity: str, parameter: str | None, breaker: dict[str, Any]) -> bool:
        """Does an event of this kind, severity, parameter and breaker go to this route?"""
        if self.events and kind not in self.events:
            return False
        if self.severities and severity not in self.severities:
            return False
        if self.parameters and parameter not in self.parameters:
            return False
        if self.breakers and breaker.get("name") not in self.breakers and breaker.get("tag") not in self.breakers:
            return False
        return True


class NotificationSettings(BaseModel):
    """``[notifications]``: the routes and how the notifier paces them."""

    model_config = {"extra": "forbid"}
    routes: list[RouteSettings] = Field(default_factory=list)
    group_interval_s: float = Field(60.0, ge=0, description="a route sends at most one message per interval; "
                                    "events of a storm in between go in one message")
    max_events_per_message: int = Field(100, ge=1, le=10_000)
    retry_min_s: float = Field(1.0, gt=0, description="first wait after a failed attempt; doubles each time")
    retry_max_s: float = Field(600.0, gt=0, description="longest wait between attempts")
    prognosis_weeks: float = Field(12.0, gt=0, description="an event when a prognosis enters its last N weeks")
    poll_s: float = Field(1.0, gt=0, le=60, description="how often the notifier looks for new events")
    page_url: str = Field("", description="the service's address, for links in messages (e.g. https://hvcb.example)")

    @model_validator(mode="after")
    def _distinct(self):
        names = [r.name for r in self.routes]
        if len(set(names)) != len(names):
            raise ValueError("two [[notifications.routes]] have the same name")
        if self.retry_min_s > self.retry_max_s:
            raise ValueError("[notifications] retry_min_s must not exceed retry_max_s")
        return self


def from_section(section) -> NotificationSettings:
    """The ``[notifications]`` section of the settings (a mapping, as read from the TOML file or
    given as a keyword) as a NotificationSettings: the notifications read their own section, so
    the settings layer needs nothing from here. Bad values raise ValueError in words."""
    if isinstance(section, NotificationSettings):
        return section
    if not isinstance(section, dict):
        raise ValueError(f"[notifications] must be a table of settings, got {type(section).__name__}")
    try:
        return NotificationSettings.model_validate(section)
    except ValidationError as exc:
        raise ValueError("bad settings: " + "; ".join(
            f"notifications.{'.'.join(map(str, e['loc']))}: {e['msg'].removeprefix('Value error, ')}"
            for e in exc.errors())) from None


def _from_env(name: str, where: str) -> str:
    value = os.environ.get(name, "")
    if not value:
        raise ValueError(f"{where}: the environment variable {name} is empty or not set")
    return value


assert set(KINDS) == set(Kind.__args__) and SEVERITIES == ("warning", "alarm")
