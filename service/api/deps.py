"""FastAPI dependencies: the session, the settings, the monitor and the caller's role (the key
check itself is in keys.py)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Request
from sqlalchemy.orm import Session

from service.settings import Settings

from .keys import Principal, require


def get_session(request: Request) -> Iterator[Session]:
    """The request's session; closed (its connection back in the pool) as soon as the handler
    returns, before the answer is serialised and sent (``scope="function"``)."""
    with request.app.state.Session() as session:
        yield session


async def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_monitor(request: Request):
    return request.app.state.monitor


SessionDep = Annotated[Session, Depends(get_session, scope="function")]
SettingsDep = Annotated[Settings, Depends(get_settings)]
MonitorDep = Annotated[object, Depends(get_monitor)]
ReaderDep = Annotated[Principal, Depends(require("reader"))]
OperatorDep = Annotated[Principal, Depends(require("operator"))]
AdminDep = Annotated[Principal, Depends(require("admin"))]
UploaderDep = Annotated[Principal, Depends(require("operator", also=("agent",)))]
