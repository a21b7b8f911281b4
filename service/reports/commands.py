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


def cmd_report(args) -> int:
    from pathlib import Path

    from sqlalchemy.exc import SQLAlchemyError

    from service.settings import command_settings
    from service.storage.db import make_engine, session_factory
    from service.storage.schema import NotMigrated, check_schema

    from .content import gather
    from .pdf import report_pdf
    from .window import Window

    window = Window(parse_time(args.start, "--from"), parse_time(args.end, "--to"))
    out = Path(args.output)
    if not out.parent.is_dir():
        raise UserError(f"cannot write {out}: the folder {out.parent} does not exist")
    settings = command_settings(args)
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
