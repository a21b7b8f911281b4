"""Templates (Jinja2, autoescaped) and the headers every page answer carries."""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

from fastapi import Request
from fastapi.templating import Jinja2Templates
from jinja2 import Environment, FileSystemLoader, select_autoescape

# significant and signed_change are imported from here by their tests
from service.display import (finite, parameter_label, parameter_name, parameter_short, plural, quantity, significant,  # noqa: F401
                             signed_change, signed_number, unit, watched_words)

from service.findings import likely_cause

HERE = Path(__file__).resolve().parent

# Everything from this origin only: no CDN, no inline script, nothing a stored string could run.
CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; connect-src 'self'; "
       "font-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'")


def _utc(t: datetime | None) -> str:
    if t is None:
        return "—"
    if t.tzinfo is None:
        t = t.replace(tzinfo=timezone.utc)
    return t.astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M:%S") + " UTC"


def _iso(t: datetime | None) -> str:
    if t is None:
        return ""
    if t.tzinfo is None:
        t = t.replace(tzinfo=timezone.utc)
    return t.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")


def _num(v, digits: int = 4) -> str:
    """A number with ``digits`` significant digits in plain notation, or a dash."""
    return significant(v, digits, grouping=True)


def _fixed(v, decimals: int = 2, scale: float = 1.0) -> str:
    v = finite(v)
    if v is None:
        return "—"
    return f"{v * scale:.{decimals}f}".replace("-", "−")


def _pct_half_width(value, ci) -> str:
    if not ci or value in (None, 0):
        return "—"
    lo, hi = ci[:2]
    if lo is None or hi is None:
        return "—"
    return f"±{abs(hi - lo) / 2 / abs(value) * 100:.2f} %"


def build_templates() -> Jinja2Templates:
    env = Environment(loader=FileSystemLoader(HERE / "templates"), autoescape=select_autoescape(default=True),
                      trim_blocks=True, lstrip_blocks=True)
    from service.errors import redact_paths

    # nopath: server paths cut to file names in what the page shows (D11, docs/security.md)
    env.filters.update(utc=_utc, iso=_iso, num=_num, fixed=_fixed, pct=_pct_half_width, nopath=redact_paths,
                       sig=significant, change=signed_change, unit=unit, signed=signed_number,
                       label=parameter_label, pname=parameter_name, short=parameter_short, quantity=quantity, plural=plural,
                       cause=likely_cause, watched=watched_words)
    return Jinja2Templates(env=env)


def security_headers(resp):
    resp.headers["Content-Security-Policy"] = CSP
    resp.headers["X-Content-Type-Options"] = "nosniff"
    resp.headers["Referrer-Policy"] = "same-origin"  # browsers then send Origin on same-site POSTs
    resp.headers["X-Frame-Options"] = "DENY"
    resp.headers.setdefault("Cache-Control", "no-store")
    return resp


def page(request: Request, template: str, context: dict, status_code: int = 200):
    from service.storage import crud_web

    user = getattr(request.state, "web_user", None)
    marker = None
    if user is not None:  # the live updates start from what this page shows
        with request.app.state.Session() as session:
            marker = crud_web.change_marker(session)
    ctx = {"user": user, "csrf": user.csrf if user else "", "nav": None, "marker": marker,
           "poll_s": request.app.state.settings.web.poll_s, **context}
    resp = request.app.state.web_templates.TemplateResponse(request, template, ctx, status_code=status_code)
    return security_headers(resp)
