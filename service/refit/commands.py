"""``hvcb refit``: re-fit stored operations after a breaker file or the estimator changed."""

from __future__ import annotations

import sys
from datetime import datetime, timezone

from service.errors import UserError, in_words


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "refit", help="re-fit stored operations (keeps the old results as a superseded version)",
        description="Re-fit stored operations through the worker pool. Ctrl-C stops it; running "
                    "the same command again resumes where it stopped, without losing or doubling a "
                    "result.")
    p.add_argument("--breaker", default=None, help="only this breaker (its name)")
    p.add_argument("--since", default=None, help="only operations at or after this date (ISO 8601, UTC)")
    p.add_argument("--workers", type=int, default=None, help="local pool size (default: settings)")
    p.add_argument("--backend", choices=("local", "celery", "inline"), default="local",
                   help="local process pool, Celery workers on the settings' broker, or this process")
    p.add_argument("--batch-size", type=int, default=None,
                   help="operations per worker task (default 25); a smaller batch lands more often")
    p.add_argument("--config", default=None, help="settings TOML (default config/default.toml)")
    p.set_defaults(func=cmd_refit)


def parse_since(text: str | None) -> datetime | None:
    if text is None:
        return None
    try:
        value = datetime.fromisoformat(text)
    except ValueError:
        raise UserError(f"--since {text!r} is not a date (use ISO 8601, e.g. 2026-01-31 or "
                        "2026-01-31T12:00)") from None
    return value if value.tzinfo else value.replace(tzinfo=timezone.utc)


def _check_database(engine, url: str) -> None:
    """A missing or unmigrated database is a sentence, not a traceback."""
    from sqlalchemy.exc import SQLAlchemyError

    from service.storage.schema import NotMigrated, check_schema

    where = url.split("@")[-1]
    try:
        check_schema(engine)
    except NotMigrated as exc:
        engine.dispose()
        raise UserError(f"database {where}: {exc}") from None
    except SQLAlchemyError as exc:
        engine.dispose()
        raise UserError(f"database {where} cannot be reached ({in_words(exc)}); check "
                        "DATABASE_URL or the settings") from None


def cmd_refit(args) -> int:
    from service.settings import command_settings
    from service.jobs.fit import JobOptions
    from service.progress import progress
    from service.storage.db import make_engine, session_factory

    from . import pool
    from .runs import BATCH_SIZE, run_refit, start_run

    since = parse_since(args.since)
    if args.workers is not None and args.workers < 1:
        raise UserError("--workers must be at least 1")
    if args.batch_size is not None and args.batch_size < 1:
        raise UserError("--batch-size must be at least 1")
    settings = command_settings(args)
    engine = make_engine(settings.sqlalchemy_url)
    Session = session_factory(engine)
    _check_database(engine, settings.sqlalchemy_url)
    options = JobOptions.from_settings(settings)
    with Session() as session, session.begin():
        run, resumed = start_run(session, breaker=args.breaker, since=since, requested_by="hvcb refit")
        run_id, total, landed = run.id, run.total, run.done + run.failed
    if resumed:
        print(f"resuming refit run {run_id}: {landed} of {total} operations already re-fitted", flush=True)
    else:
        print(f"refit run {run_id}: {total} operations", flush=True)
    if args.backend == "celery":
        if not settings.broker_url:
            raise UserError("--backend celery needs HVCB_BROKER_URL (the workers' broker)")
        submit = pool.celery(settings, Session)
    elif args.backend == "inline":
        submit = pool.inline(options)
    else:
        submit = pool.local_pool(options, args.workers or settings.workers)
    bar = progress(total, desc=f"refit {run_id}", unit="fit", initial=landed)
    seen = {"first": True}

    def on_progress(n, _total):
        if seen.pop("first", False):
            return  # the initial count is already on the bar
        bar.update(n)

    try:
        run = run_refit(Session, run_id, submit_batches=submit, options=options, on_progress=on_progress,
                        batch_size=args.batch_size or BATCH_SIZE)
    except KeyboardInterrupt:
        bar.close()
        print(f"\nrefit run {run_id} interrupted; run the same command again to resume", file=sys.stderr)
        return 130
    finally:
        engine.dispose()
    bar.close()
    print(f"refit run {run_id}: {run.done} re-fitted, {run.failed} kept their result (re-fit failed)")
    if run.reason:
        for line in run.reason.splitlines()[:5]:
            print(f"  {line}")
    return 0
