"""What every page handler shares: the path id, the role dependencies, the session, the redirects.

Its own module so that the route modules (routes, routes_alarms, routes_diagnoses) import it and
not each other: no import circle between them.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, HTTPException, Path as PathParam, Request
from fastapi.responses import RedirectResponse

from . import auth
from .auth import WebUser
from .render import security_headers

MAX_ID = 2_147_483_647  # the largest id the database's INTEGER key holds
Id = Annotated[int, PathParam(ge=1, le=MAX_ID)]

Reader = Annotated[WebUser, Depends(auth.require_page("reader"))]


def poster(role: str):
    """Dependency of a POST: signed in with ``role`` or more, and a valid CSRF token."""

    async def dependency(request: Request, user: WebUser = Depends(auth.require_page(role))) -> WebUser:
        await auth.require_csrf(request, user)
        return user

    return dependency


ReaderPost = Annotated[WebUser, Depends(poster("reader"))]
OperatorPost = Annotated[WebUser, Depends(poster("operator"))]
AdminPost = Annotated[WebUser, Depends(poster("admin"))]


def db_session(request: Request):
    """A new database session of the app (use it as a context manager)."""
    return request.app.state.Session()


def not_found(what: str):
    """404 with ``no <what>`` in words."""
    raise HTTPException(404, f"no {what}")


def safe_next(target: str | None) -> str:
    """Only a local path: never redirect to another site."""
    if not target or not target.startswith("/") or target.startswith("//") or "\\" in target:
        return "/"
    return target


def back(request: Request, default: str):
    """303 to the page the form came from (its ``back`` query, a local path) or to ``default``."""
    target = request.query_params.get("back")
    return security_headers(RedirectResponse(safe_next(target) if target else default, status_code=303))


def form_temperature(text: str) -> float | None:
    """The optional temperature field of a form [°C]; HTTPException 422 in words."""
    from service.alarms import check_temperature

    text = (text or "").strip().replace(",", ".")
    if not text:
        return None
    try:
        return check_temperature(text, "the temperature")
    except ValueError as exc:
        raise HTTPException(422, str(exc)) from None
