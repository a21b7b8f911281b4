"""The OpenAPI document as the exact contract (docs/rest-api.md, "Errors").

Every operation is completed from what it has, so a new route gets the same treatment without a
word of its own:

- a key (``security``): 401 (no key, or an unknown or revoked one), 403 (role too low) and 429
  (too many wrong keys from this address, service/api/throttle.py);
- path parameters: 404; parameters or a body: 422; a body: 400 (not JSON or not UTF-8), 408
  (the body stalled) and 413 (too large), from the request guard (service/api/guard.py);
- every operation: 503 (the database does not answer, or the service sheds load);
- no key: ``security: []``, public; an optional key (``/healthz``): ``[{}, {key}]``.

Every error answers one body, :class:`ErrorBody`; the handlers installed here make FastAPI's
own answers (422 from validation, 400 from an unreadable body) send it too.
"""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.utils import get_openapi
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from .schemas import ErrorBody

ERROR_REF = "#/components/schemas/ErrorBody"
RETRY_AFTER = {"Retry-After": {"description": "seconds to wait before trying again", "schema": {"type": "integer"}}}
# FastAPI's answer when a body cannot be decoded (invalid UTF-8 and the like), put in words
UNREADABLE_BODY = "There was an error parsing the body"

KEYED = {
    "401": ("no API key, or an unknown or revoked one: send a valid key in X-API-Key",
            {"WWW-Authenticate": {"description": "APIKey", "schema": {"type": "string"}}}),
    "403": ("the key's role is below the one this operation needs", None),
    "429": ("too many wrong keys from this address: wait Retry-After seconds (a right key still gets in)",
            RETRY_AFTER),
}
WITH_BODY = {
    "400": ("the body is not well-formed: not JSON, not UTF-8, or not the declared content type", None),
    "408": ("the body stalled or took too long to arrive", None),
    "413": ("the body is larger than the service's limit", None),
}
WITH_PATH = {"404": ("no such resource", None)}
WITH_INPUT = {"422": ("a parameter or the body is not valid: `detail` says what in words, `errors` per field",
                      None)}
ALWAYS = {"503": ("the database does not answer, or the service is busy: try again after Retry-After seconds",
                  RETRY_AFTER)}
GENERIC = {"Additional Response", "Validation Error", "Successful Response", ""}


def is_api(request: Request) -> bool:
    """A request to the JSON API (not to a page of the web)."""
    return request.url.path.startswith(("/api/", "/healthz", "/metrics"))


def _keyed(op: dict) -> bool:
    return any(req for req in op.get("security", ()))


def statuses(op: dict) -> dict[str, tuple[str, dict | None]]:
    """The error statuses ``op`` (an OpenAPI operation object) can answer: {status: (why, headers)}."""
    params = op.get("parameters", [])
    out = dict(ALWAYS)
    if _keyed(op):
        out |= KEYED
    if any(p.get("in") == "path" for p in params):
        out |= WITH_PATH
    if "requestBody" in op:
        out |= WITH_BODY
    if params or "requestBody" in op:
        out |= WITH_INPUT
    return out


def complete(op: dict) -> None:
    """Document every error status of ``op`` with the one error body; mark it public if keyless."""
    if not op.get("security"):
        op["security"] = []  # public: no key needed
    responses = op.setdefault("responses", {})
    for status, (why, headers) in statuses(op).items():
        entry = responses.setdefault(status, {})
        said = entry.get("description", "")
        entry["description"] = why if said in GENERIC else (said if said == why else f"{said}; or {why}")
        if headers:
            entry["headers"] = {**headers, **entry.get("headers", {})}
    for status, entry in responses.items():
        if status[0] in "45":  # errors declared by the route itself (404, 409, 410...) too
            entry["content"] = {"application/json": {"schema": {"$ref": ERROR_REF}}}
            if entry.get("description", "") in GENERIC:
                entry["description"] = "refused: `detail` says why"
    op["responses"] = dict(sorted(responses.items()))


def operation_id(route) -> str:
    """The operation's id in the document, and so the function's name in a generated client: the
    route function's own name (``list_breakers``), not FastAPI's default with the path appended.
    Unique by test (tests/service/test_api_contract.py)."""
    return route.name


def contract(app: FastAPI) -> dict:
    """The app's OpenAPI document, completed (built once, then cached like FastAPI's own)."""
    if app.openapi_schema:
        return app.openapi_schema
    doc = get_openapi(title=app.title, version=app.version, description=app.description, routes=app.routes)
    schemas = doc.setdefault("components", {}).setdefault("schemas", {})
    body = ErrorBody.model_json_schema(ref_template="#/components/schemas/{model}")
    schemas.update(body.pop("$defs", {}))
    schemas["ErrorBody"] = body
    for item in doc.get("paths", {}).values():
        for op in item.values():
            complete(op)
    for unused in ("HTTPValidationError", "ValidationError"):  # FastAPI's 422 body, replaced by ErrorBody
        schemas.pop(unused, None)
    app.openapi_schema = doc
    return doc


def validation_body(exc: RequestValidationError) -> dict:
    """FastAPI's validation errors as one :class:`ErrorBody`: the words first, then per field."""
    errors = []
    for e in exc.errors():
        loc = [p for p in e.get("loc", ()) if p not in ("body", "query", "path", "header", "cookie")] or \
            list(e.get("loc", ()))[:1]
        errors.append({"loc": [p if isinstance(p, int) else str(p) for p in loc], "msg": str(e.get("msg", "")),
                       "type": str(e.get("type", ""))})
    words = "; ".join(f"{'.'.join(map(str, x['loc'])) or 'request'}: {x['msg']}" for x in errors)
    return ErrorBody(detail=words or "the request is not valid", errors=errors).model_dump(exclude_none=True)


def install(app: FastAPI) -> None:
    """The completed document at /openapi.json, and error answers that match it. Call after the
    web is mounted: its handlers keep answering its pages."""
    app.openapi = lambda: contract(app)
    pages_invalid = app.exception_handlers.get(RequestValidationError)
    pages_http = app.exception_handlers.get(StarletteHTTPException)

    async def invalid(request: Request, exc: RequestValidationError):
        if is_api(request) or pages_invalid is None:
            return JSONResponse(validation_body(exc), status_code=422)
        return await pages_invalid(request, exc)

    async def http_error(request: Request, exc: StarletteHTTPException):
        if is_api(request) or pages_http is None:
            detail = exc.detail
            if exc.status_code == 400 and detail == UNREADABLE_BODY:
                detail = "the body is not well-formed: send UTF-8 JSON (Content-Type: application/json)"
            if exc.status_code == 405 and detail == "Method Not Allowed":
                detail = f"{request.method} is not allowed here: see the Allow header"
            return JSONResponse({"detail": str(detail)}, status_code=exc.status_code, headers=exc.headers)
        return await pages_http(request, exc)

    app.add_exception_handler(RequestValidationError, invalid)
    app.add_exception_handler(StarletteHTTPException, http_error)
