"""Sign-in with an API key, the session cookie and CSRF protection of the web page.

The cookie holds a random session token signed with itsdangerous (timestamped, so an old cookie
fails even before the database is asked); the database keeps only the token's SHA-256, the key
it belongs to and the expiry, so sign-out and key revocation end the session at once. The API
key itself is only ever in the sign-in POST body. CSRF: every form carries an HMAC of the
session token (synchroniser token); the sign-in form, before any session, is bound to a short
pre-session cookie the same way.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path
from urllib.parse import urlsplit

from fastapi import Request
from itsdangerous import BadSignature, SignatureExpired, URLSafeTimedSerializer

from service.storage import crud, crud_web
from service.storage.models import utcnow

COOKIE = "hvcb_session"
PRE_COOKIE = "hvcb_signin"
PRE_MAX_AGE_S = 600
WEB_ROLES = ("reader", "operator", "admin")  # roles that may sign in to the page


def client_address(scope) -> str:
    """The client's address (uvicorn has already applied X-Forwarded-For from trusted proxies)."""
    client = scope.get("client")
    return client[0] if client else "unknown"


class WebAuthError(Exception):
    """Raised by the page dependencies; the app's handler turns it into a page or JSON answer.

    kind: "missing" (no cookie: go and sign in), "invalid" (forged, expired or ended: 401),
    "forbidden" (role too low: 403), "csrf" (POST without a valid token: 403).
    """

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind, self.message = kind, message


@dataclass(frozen=True)
class WebUser:
    key_id: int
    name: str
    role: str
    token: str
    csrf: str

    def can(self, role: str) -> bool:
        return crud.ROLE_RANK.get(self.role, -1) >= crud.ROLE_RANK[role]


def load_secret(settings) -> bytes:
    """The signing key: ``[web] secret`` or a random one generated once into <data_dir>/web.secret (0600)."""
    if settings.web.secret:
        return settings.web.secret.encode()
    path = Path(settings.data_dir) / "web.secret"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:  # another process won the race
            pass
        else:
            with os.fdopen(fd, "w") as fh:
                fh.write(secrets.token_urlsafe(48) + "\n")
    return path.read_text().strip().encode()


class SessionSigner:
    def __init__(self, secret: bytes, lifetime_s: float):
        self.lifetime_s = lifetime_s
        self._secret = secret
        self._session = URLSafeTimedSerializer(secret, salt="hvcb-web-session")
        self._pre = URLSafeTimedSerializer(secret, salt="hvcb-web-signin")

    def sign(self, token: str) -> str:
        return self._session.dumps(token)

    def unsign(self, cookie: str) -> str:
        """The token; raises WebAuthError("invalid") for a forged or expired cookie."""
        try:
            token = self._session.loads(cookie, max_age=self.lifetime_s)
        except SignatureExpired:
            raise WebAuthError("invalid", "your session has expired: sign in again") from None
        except BadSignature:
            raise WebAuthError("invalid", "the session cookie is not valid: sign in again") from None
        if not isinstance(token, str):
            raise WebAuthError("invalid", "the session cookie is not valid: sign in again")
        return token

    def csrf_for(self, token: str) -> str:
        return hmac.new(self._secret, b"csrf\0" + token.encode(), hashlib.sha256).hexdigest()

    def pre_cookie(self) -> tuple[str, str]:
        """(cookie value, CSRF token) for the sign-in form."""
        nonce = secrets.token_urlsafe(24)
        return self._pre.dumps(nonce), self.csrf_for("signin\0" + nonce)

    def check_pre(self, cookie: str | None, csrf: str | None) -> bool:
        if not cookie or not csrf:
            return False
        try:
            nonce = self._pre.loads(cookie, max_age=PRE_MAX_AGE_S)
        except BadSignature:
            return False
        return hmac.compare_digest(self.csrf_for("signin\0" + str(nonce)), csrf)


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def signer(request: Request) -> SessionSigner:
    return request.app.state.web_signer


def secure_cookie(request: Request) -> bool:
    mode = request.app.state.settings.web.secure_cookie
    return mode == "always" or (mode == "auto" and request.url.scheme == "https")


def set_cookie(response, request: Request, name: str, value: str, max_age: int, path: str = "/") -> None:
    response.set_cookie(name, value, max_age=max_age, path=path, httponly=True, samesite="strict",
                        secure=secure_cookie(request))


def sign_in(request: Request, key: str) -> tuple[str, WebUser]:
    """Check the key and open a session. Returns (cookie value, user); raises WebAuthError. A
    writer holding SQLite's lock makes it wait and try again (bounded), not answer 503."""
    from service.storage.db import retry_locked

    return retry_locked(lambda: _sign_in(request, key))


def _sign_in(request: Request, key: str) -> tuple[str, WebUser]:
    with request.app.state.Session() as session, session.begin():
        row = crud.find_api_key(session, key=key.strip())
        if row is None:
            raise WebAuthError("signin", "unknown or revoked API key")
        if row.role not in WEB_ROLES:
            raise WebAuthError("signin", f"a key with the {row.role} role cannot sign in to the web page")
        token = secrets.token_urlsafe(32)
        lifetime = timedelta(seconds=signer(request).lifetime_s)
        crud_web.create_web_session(session, token_hash=token_hash(token), key_id=row.id,
                                    expires_at=utcnow() + lifetime)
        crud_web.purge_web_sessions(session, before=utcnow() - timedelta(days=7))
        user = WebUser(row.id, row.name, row.role, token, signer(request).csrf_for(token))
    return signer(request).sign(token), user


def sign_out(request: Request, user: WebUser) -> None:
    from service.storage.db import retry_locked

    def end():
        with request.app.state.Session() as session, session.begin():
            crud_web.end_web_session(session, token_hash=token_hash(user.token))
    retry_locked(end)


def end_presented_session(request: Request) -> bool:
    """End the session whose cookie this request carries, if it is a valid one (sign-in rotates
    the session: an old cookie, perhaps seen by someone else, stops working). True if one ended."""
    cookie = request.cookies.get(COOKIE)
    if not cookie:
        return False
    try:
        token = signer(request).unsign(cookie)
    except WebAuthError:
        return False
    from service.storage.db import retry_locked

    def end():
        with request.app.state.Session() as session, session.begin():
            return crud_web.end_web_session(session, token_hash=token_hash(token))
    return retry_locked(end)


def current_user(request: Request) -> WebUser:
    """The signed-in user of this request; raises WebAuthError."""
    cookie = request.cookies.get(COOKIE)
    if not cookie:
        raise WebAuthError("missing", "sign in with an API key")
    token = signer(request).unsign(cookie)
    with request.app.state.Session() as session:
        found = crud_web.find_web_session(session, token_hash=token_hash(token))
    if found is None:
        raise WebAuthError("invalid", "your session has ended: sign in again")
    _, key = found
    return WebUser(key.id, key.name, key.role, token, signer(request).csrf_for(token))


def require_page(role: str = "reader"):
    """Dependency for pages and their data: the user, 403 below ``role``."""

    def dependency(request: Request) -> WebUser:
        user = current_user(request)
        request.state.web_user = user  # the error page shows who is signed in too
        if not user.can(role):
            raise WebAuthError("forbidden", f"this needs the {role} role; you are signed in as {user.role}")
        return user

    return dependency


async def require_csrf(request: Request, user: WebUser) -> None:
    """A POST must carry the session's CSRF token (form field ``csrf_token`` or header X-CSRF-Token)
    and, when the browser says where it comes from, come from this site."""
    origin = request.headers.get("origin")
    if origin:
        # compare hosts only: behind a TLS proxy the app may see http while the browser says https
        hosts = {request.url.netloc, request.headers.get("x-forwarded-host")}
        if urlsplit(origin).netloc not in hosts:
            raise WebAuthError("csrf", "this form was sent from another site")
    sent = request.headers.get("x-csrf-token")
    if not sent:
        form = await request.form()
        sent = form.get("csrf_token")
    if not isinstance(sent, str) or not hmac.compare_digest(sent, user.csrf):
        raise WebAuthError("csrf", "the form's security token is missing or stale: reload the page and try again")
