"""/api/v1/keys: admins list, create and revoke API keys. Two revocations are refused with 409,
so that no request can lock its caller or the service out (docs/rest-api.md, "Keys"): a key
cannot revoke itself (another admin key does it), and the last active admin key stays."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Path as PathParam, Request

from service.storage import crud
from service.storage.models import ApiKeyRow

from . import schemas as s
from .deps import AdminDep, SessionDep

router = APIRouter(prefix="/api/v1", tags=["keys"])

KeyId = Annotated[int, PathParam(ge=1, le=2_147_483_647, description="API key id")]
OWN_KEY = ("key {id} is the key making this request: a key cannot revoke itself, so that nobody locks "
           "themselves out by mistake. Revoke it with another admin key (create one with POST /api/v1/keys, "
           "role admin, or `hvcb key NAME --role admin` on the server)")
LAST_ADMIN = ("key {id} is the last active admin key: revoking it would leave nobody able to manage keys. "
              "Create another admin key first (POST /api/v1/keys with role admin, or `hvcb key NAME --role admin` "
              "on the server), sign in with it, then revoke this one")


@router.get("/keys", response_model=list[s.ApiKeyPublic])
def list_keys(session: SessionDep, _: AdminDep):
    return crud.list_api_keys(session)


@router.post("/keys", response_model=s.ApiKeyCreated, status_code=201)
def create_key(body: s.ApiKeyCreate, session: SessionDep, _: AdminDep):
    row, key = crud.create_api_key(session, name=body.name, role=body.role)
    session.commit()
    return s.ApiKeyCreated(**s.ApiKeyPublic.model_validate(row).model_dump(), key=key)


@router.delete("/keys/{key_id}", response_model=s.ApiKeyPublic,
               responses={409: {"description": "the key making the request, or the last active admin key: "
                                               "revoke it with another admin key, created first"}})
def revoke_key(key_id: KeyId, request: Request, session: SessionDep, who: AdminDep):
    """Revoke a key (admin). A revoked key stops working within the key cache's few seconds.
    Refused with 409, the key working on: the key making the request (another admin key revokes
    it) and the last active admin key."""
    row = session.get(ApiKeyRow, key_id)
    if row is None:
        raise HTTPException(404, f"no key {key_id}")
    if row.id == who.key_id and row.revoked_at is None:
        raise HTTPException(409, OWN_KEY.format(id=key_id))
    try:
        crud.revoke_api_key(session, row=row)
    except crud.LastAdminKey:
        raise HTTPException(409, LAST_ADMIN.format(id=key_id)) from None
    session.commit()
    request.app.state.key_cache.clear()
    return row
