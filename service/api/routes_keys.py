"""/api/v1/keys: admins list, create and revoke API keys. The last active admin key cannot be
revoked (409): that would leave nobody able to manage keys (docs/rest-api.md, "Keys")."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Path as PathParam, Request

from service.storage import crud
from service.storage.models import ApiKeyRow

from . import schemas as s
from .deps import AdminDep, SessionDep

router = APIRouter(prefix="/api/v1", tags=["keys"])

KeyId = Annotated[int, PathParam(ge=1, le=2_147_483_647, description="API key id")]
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
               responses={409: {"description": "the last active admin key: create another admin key first"}})
def revoke_key(key_id: KeyId, request: Request, session: SessionDep, _: AdminDep):
    """Revoke a key (admin). A revoked key stops working within the key cache's few seconds.
    Revoking one's own key is allowed while another admin key is active; the last active admin
    key is refused with 409 and keeps working."""
    row = session.get(ApiKeyRow, key_id)
    if row is None:
        raise HTTPException(404, f"no key {key_id}")
    try:
        crud.revoke_api_key(session, row=row)
    except crud.LastAdminKey:
        raise HTTPException(409, LAST_ADMIN.format(id=key_id)) from None
    session.commit()
    request.app.state.key_cache.clear()
    return row
