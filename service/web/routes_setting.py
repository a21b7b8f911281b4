"""The operation page's spring setting: record the page's close–open pair as the breaker's
commissioning pair (an operator, with the nut setting it was recorded at)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request

from service.storage import crud
from service.storage.spring_references import NoPair, record_reference

from .handlers import Id, OperatorPost, back, db_session, not_found

router = APIRouter(include_in_schema=False)


@router.post("/operations/{operation_id}/commission")
def commission(request: Request, operation_id: Id, user: OperatorPost,
               known_steps: Annotated[float, Form(ge=-50, le=50)]):
    with db_session(request) as session:
        op = crud.get_operation(session, operation_id=operation_id) or not_found(f"operation {operation_id}")
        breaker = crud.breaker_model(crud.get_breaker(session, breaker_id=op.breaker_id))
        try:
            record_reference(session, op, breaker, known_steps=known_steps, by=f"{user.name} (web)")
        except NoPair as exc:
            raise HTTPException(409, str(exc)) from None
        session.commit()
    return back(request, f"/operations/{operation_id}#spring-setting")
