"""``hvcb report``: a breaker's condition report as PDF, from the service's database."""

from __future__ import annotations

import time
from datetime import datetime, timezone

from service.errors import UserError, in_words


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "report", help="a breaker's condition report (PDF)",
        description="Write a breaker's condition report: its identity and file, the latest opening and "
                    "closing against the breaker file's limits, the parameter trends, the alarms, the "
                    "prognosis, the last diagnosis and the method (docs/reports.md).")
    p.add_argument("breaker", help="the breaker's name, tag or id")
    p.add_argument("--from", dest="start", default=None, help="operations at or after this time (ISO 8601, UTC)")
    p.add_argument("--to", dest="end", default=None, help="operations at or before this time (ISO 8601, UTC)")
    p.add_argument("-o", "--output", required=True, help="the PDF file to write")
    p.add_argument("--config", default=None, help="settings TOML (default config/default.toml)")
    p.add_argument("--url", default=None,
                   help="the running service to ask for the report (default: $HVCB_URL, else the settings' "
                        "[server] host and port); the report is drawn from the database here when none answers")
    p.add_argument("--key", default=None,
                   help="API key for the service (default: $HVCB_API_KEY, else <data_dir>/admin.key)")
    p.add_argument("--local", action="store_true", help="draw it here from the database, without asking a service")
    p.set_defaults(func=cmd_report)


def parse_time(text: str | None, option: str) -> datetime | None:
    if text is None:
        return None
    try:
        value = datetime.fromisoformat(text)
    except ValueError:
        raise UserError(f"{option} {text!r} is not a time (use ISO 8601, e.g. 2026-01-31 or "
                        "2026-01-31T12:00)") from None
    return value if value.tzinfo else value.replace(tzinfo=timezone.utc)


def find_breaker(session, ref: str):
    """The breaker named, tagged or numbered ``ref``; a sentence when there is none."""
    from sqlalchemy import or_, select

    from service.storage.models import BreakerRow

    b = session.scalar(select(BreakerRow).where(or_(BreakerRow.name == ref, BreakerRow.tag == ref)))
    if b is None and ref.isdigit():
        b = session.get(BreakerRow, int(ref))
    if b is None:
        names = ", ".join(session.scalars(select(BreakerRow.name).order_by(BreakerRow.name).limit(20))) or "none"
        raise UserError(f"no breaker named, tagged or numbered {ref!r} (breakers: {names})")
    return b


def service_url(args, settings) -> str:
    """Where a running service would answer: ``--url``, ``$HVCB_URL``, else the settings' server."""
    import os

    url = args.url or os.environ.get("HVCB_URL")
    if url:
        return url.rstrip("/")
    host = settings.host if settings.host not in ("0.0.0.0", "::", "") else "127.0.0.1"
    return f"http://{host}:{settings.port}"


def service_key(args, settings) -> str | None:
    import os
    from pathlib import Path

    key = args.key or os.environ.get("HVCB_API_KEY")
    if key:
        return key.strip()
    path = Path(settings.data_dir) / "admin.key"
    try:
        return path.read_text(encoding="utf-8").strip() or None
    except OSError:
        return None


class NoService(Exception):
    """No service answered at the address: the report is drawn here instead."""


def report_from_service(url: str, key: str | None, breaker: str, start: datetime | None, end: datetime | None,
                        *, connect_timeout_s: float = 5.0, wait_s: float = 600.0) -> bytes:
    """The PDF as the running service draws it (the page's button: warm, in its workers).

    Raises ``NoService`` when nothing answers at ``url``, ``UserError`` in words when it answers
    but refuses (the key, the breaker, the window).
    """
    import json
    import urllib.error
    import urllib.parse
    import urllib.request

    query = urllib.parse.urlencode({k: v.isoformat() for k, v in (("from", start), ("to", end)) if v is not None})
    target = f"{url}/api/v1/breakers/{urllib.parse.quote(breaker, safe='')}/report" + (f"?{query}" if query else "")
    headers = {"X-API-Key": key} if key else {}
    try:  # is anything there? (/healthz is public and answers from a snapshot)
        urllib.request.urlopen(f"{url}/healthz", timeout=connect_timeout_s).close()
    except urllib.error.HTTPError:
        pass  # it answers, if not healthy: the report request says more
    except (urllib.error.URLError, OSError) as exc:
        raise NoService(str(exc)) from None
    deadline = time.monotonic() + wait_s
    while True:
        request = urllib.request.Request(target, headers=headers)
        try:
            # the service waits up to its [server] report_wait_s for the PDF before it answers 202
            with urllib.request.urlopen(request, timeout=wait_s) as answer:
                body, status = answer.read(), answer.status
                location = answer.headers.get("Location")
        except urllib.error.HTTPError as exc:
            try:
                detail = json.loads(exc.read() or b"{}").get("detail")
            except ValueError:
                detail = None
            why = detail if isinstance(detail, str) else exc.reason
            if exc.code in (401, 403):
                why = f"{why}: give a reader key with --key or $HVCB_API_KEY"
            raise UserError(f"the service at {url} refused the report ({exc.code}): {why}") from None
        except (urllib.error.URLError, OSError) as exc:
            raise UserError(f"the service at {url} stopped answering while it drew the report ({in_words(exc)})") from None
        if status == 200:
            return body
        if status != 202 or not location:
            raise UserError(f"the service at {url} answered {status} to the report request")
        if time.monotonic() > deadline:
            raise UserError(f"the service at {url} has not finished the report in {wait_s:.0f} s")
        target = urllib.parse.urljoin(url + "/", location.lstrip("/"))
        time.sleep(0.2)


def cmd_report(args) -> int:
    from pathlib import Path

    from service.settings import command_settings

    from .window import Window

    start, end = parse_time(args.start, "--from"), parse_time(args.end, "--to")
    try:
        window = Window(start, end)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    out = Path(args.output)
    if not out.parent.is_dir():
        raise UserError(f"cannot write {out}: the folder {out.parent} does not exist")
    settings = command_settings(args)
    if not args.local:
        url = service_url(args, settings)
        t0 = time.perf_counter()
        try:
            data = report_from_service(url, service_key(args, settings), args.breaker, start, end)
        except NoService:
            if args.url:
                raise UserError(f"no service answers at {args.url} (leave --url out to draw the report "
                                "here from the database)") from None
        else:
            out.write_bytes(data)
            print(f"wrote {out} ({len(data) / 1e3:.0f} kB, {time.perf_counter() - t0:.1f} s): condition report of "
                  f"{args.breaker}, drawn by the service at {url}")
            return 0
    return _report_here(args, settings, out, window)


def _report_here(args, settings, out, window) -> int:
    """The report drawn in this process from the settings' database."""
    from sqlalchemy.exc import SQLAlchemyError

    from service.storage.db import make_engine, session_factory
    from service.storage.schema import NotMigrated, check_schema

    from .content import gather
    from .pdf import report_pdf

    engine = make_engine(settings.sqlalchemy_url)
    where = settings.sqlalchemy_url.split("@")[-1]
    t0 = time.perf_counter()
    try:
        check_schema(engine)
        with session_factory(engine)() as session:
            content = gather(session, breaker=find_breaker(session, args.breaker), settings=settings.drift_settings,
                             window=window)
    except NotMigrated as exc:
        raise UserError(f"database {where}: {exc}") from None
    except SQLAlchemyError as exc:
        raise UserError(f"database {where} cannot be read ({in_words(exc)}); check DATABASE_URL or the "
                        "settings") from None
    finally:
        engine.dispose()
    data = report_pdf(content, out)
    print(f"wrote {out} ({len(data) / 1e3:.0f} kB, {time.perf_counter() - t0:.1f} s): condition report of "
          f"{content.breaker.name}, {window.words()}")
    return 0
