"""Templates (Jinja2, autoescaped) and the headers every page answer carries."""

from __future__ import annotations

import math
from datetime import datetime, timezone
from pathlib import Path

from fastapi import Request
from fastapi.templating import Jinja2Templates
from jinja2 import Environment, FileSystemLoader, select_autoescape

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


def _finite(v) -> float | None:
    """``v`` as a finite float, or None (no number, NaN, infinite)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _num(v, digits: int = 4) -> str:
    """A number with ``digits`` significant digits, or a dash."""
    v = _finite(v)
    if v is None:
        return "—"
    return f"{v:.{digits}g}" if abs(v) < 1e5 else f"{v:.{digits}e}"


def _fixed(v, decimals: int = 2, scale: float = 1.0) -> str:
    if v is None:
        return "—"
    try:
        v = float(v) * scale
    except (TypeError, ValueError):
        return "—"
    return f"{v:.{decimals}f}" if math.isfinite(v) else "—"


def significant(v, digits: int = 3) -> str:
    """``v`` to ``digits`` significant figures in plain notation (3419.9 -> "3420", 3.70406 -> "3.70"),
    a minus sign for negatives, a dash for no number."""
    v = _finite(v)
    if v is None:
        return "—"
    if v == 0:
        return "0"
    decimals = max(0, digits - 1 - math.floor(math.log10(abs(v))))
    text = f"{round(v, decimals):.{decimals}f}"
    return "0" if float(text) == 0 else text.replace("-", "−")


def signed_change(rel, decimals: int = 1) -> str:
    """A relative change as a signed percentage ("−5.0 %", "+0.3 %"); one that rounds to zero is
    "0.0 %", never "−0.0 %"."""
    rel = _finite(rel)
    if rel is None:
        return "—"
    pct = round(rel * 100, decimals)
    if pct == 0:
        return f"{0:.{decimals}f} %"
    return f"{pct:+.{decimals}f} %".replace("-", "−")


def signed_number(v, decimals: int = 2) -> str:
    """A signed number ("+0.42", "−1.30", "0.00": never "−0.00"), a dash for no number."""
    v = _finite(v)
    if v is None:
        return "—"
    text = f"{v:+.{decimals}f}"
    return f"{0:.{decimals}f}" if float(text) == 0 else text.replace("-", "−")


def _unit(name: str) -> str:
    from service.mechanics.nomenclature import UNITS

    return UNITS.get(name, "")


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
                       sig=significant, change=signed_change, unit=_unit, signed=signed_number)
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
