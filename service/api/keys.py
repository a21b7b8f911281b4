"""Who is calling: the API key in X-API-Key, checked (cached a few seconds), throttled when wrong,
and its role compared with the one an operation needs (docs/security.md)."""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import dataclass
from typing import Annotated

import anyio.to_thread
from fastapi import HTTPException, Request, Security
from fastapi.security import APIKeyHeader
from sqlalchemy.exc import DBAPIError, OperationalError

from service.storage import crud
from service.web.auth import client_address

api_key_header = APIKeyHeader(name="X-API-Key", auto_error=False,
                              description="API key; roles reader < operator < admin; agent may only upload")


@dataclass(frozen=True)
class Principal:
    key_id: int
    name: str
    role: str


class KeyCache:
    """Verified key hashes for a few seconds, so SCADA polling does not hit the DB per request.
    A revoked key stops working within ``ttl_s``."""

    def __init__(self, ttl_s: float = 5.0):
        self.ttl_s = ttl_s
        self._entries: dict[str, tuple[float, Principal]] = {}

    def get(self, digest: str) -> Principal | None:
        hit = self._entries.get(digest)
        if hit is None or hit[0] < time.monotonic():
            return None
        return hit[1]

    def put(self, digest: str, principal: Principal) -> None:
        if len(self._entries) > 10_000:
            self._entries.clear()
        self._entries[digest] = (time.monotonic() + self.ttl_s, principal)

    def clear(self) -> None:
        self._entries.clear()


def require(role: str, *, also: tuple[str, ...] = ()):
    """Dependency: 401 without a valid key, 403 when the key's role is below ``role`` and not
    one of ``also`` (the ``agent`` role may upload and nothing else); 429 from a throttled address."""

    async def dependency(request: Request, key: Annotated[str | None, Security(api_key_header)]) -> Principal:
        return await authorise_key(request, key, role, also=also)

    return dependency


async def authorise_key(request: Request, key: str | None, role: str, *, also: tuple[str, ...] = ()) -> Principal:
    """The key's principal, from the headers alone (the upload guard calls it before the body).

    Async so that a cached key costs no threadpool hop; only a miss touches the database.
    Wrong keys are throttled per client address (service/api/throttle.py)."""
    need = crud.ROLE_RANK[role]
    if not key:
        raise HTTPException(401, "missing API key: send it in the X-API-Key header",
                            headers={"WWW-Authenticate": "APIKey"})
    cache: KeyCache = request.app.state.key_cache
    throttle = request.app.state.auth_throttle
    address = client_address(request.scope)
    digest = crud.hash_key(key)
    principal = cache.get(digest)
    if principal is None:
        wait = throttle.blocked_for(address)
        principal = await anyio.to_thread.run_sync(_lookup, request, key, limiter=request.app.state.priority_limiter)
        if principal is None and wait > 0:
            # A blocked address learns nothing more than "wait"; a right key still gets in, so the
            # real admin behind the same NAT address as an attacker is never locked out.
            retry = max(1, math.ceil(wait))  # whole seconds, rounded up: never "try again in 0 s"
            raise HTTPException(429, f"too many wrong keys from this address: try again in {retry} s",
                                headers={"Retry-After": str(retry)})
        if principal is None:
            delay = throttle.failed(address, "API keys")
            if delay:
                await asyncio.sleep(delay)
            raise HTTPException(401, "unknown or revoked API key", headers={"WWW-Authenticate": "APIKey"})
        if wait == 0:  # a right key from a blocked address does not unblock the others behind it
            throttle.succeeded(address)
        cache.put(digest, principal)
    if crud.ROLE_RANK[principal.role] < need and principal.role not in also:
        raise HTTPException(403, f"this needs the {role} role; the key has {principal.role}")
    return principal


def _lookup(request: Request, key: str) -> Principal | None:
    from service.storage.db import retry_locked

    def find():
        with request.app.state.PrioritySession() as session:
            return crud.find_api_key(session, key=key)
    try:
        row = retry_locked(find)
    except (OperationalError, DBAPIError):
        raise HTTPException(503, "database unavailable; try again shortly") from None
    if row is None:
        return None
    return Principal(row.id, row.name, row.role)
