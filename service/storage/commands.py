"""``hvcb prune``, ``hvcb backup`` and ``hvcb restore``: keeping years of history on a bounded disk."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("prune", help="remove raw captures the retention policy no longer keeps")
    p.add_argument("--dry-run", action="store_true", help="print what would be removed and the bytes freed")
    p.add_argument("--config", default=None, help="settings TOML (default config/default.toml)")
    p.set_defaults(func=cmd_prune)

    p = sub.add_parser("backup", help="consistent copy of the database and capture files (service may run)")
    p.add_argument("dest", help="new directory to write the backup into")
    p.add_argument("--config", default=None)
    p.set_defaults(func=cmd_backup)

    p = sub.add_parser("restore", help="bring a backup back into the configured data directory and database")
    p.add_argument("src", help="a directory written by hvcb backup")
    p.add_argument("--force", action="store_true", help="overwrite a database and captures already there")
    p.add_argument("--config", default=None)
    p.set_defaults(func=cmd_restore)


def _settings(args):
    from service.settings import command_settings

    return command_settings(args)


def cmd_prune(args) -> int:
    from service.errors import UserError
    from service.storage.db import make_engine, session_factory
    from service.storage.retention import prune

    settings = _settings(args)
    policy = settings.retention
    if not policy.active:
        raise UserError("no retention policy: set [retention] max_age_days and/or max_per_breaker "
                        "in the settings (docs/operations.md); nothing pruned")
    engine = make_engine(settings.sqlalchemy_url)
    try:
        from service.storage.schema import check_schema

        check_schema(engine)
        report = prune(session_factory(engine), policy=policy, capture_dir=settings.capture_dir,
                       dry_run=args.dry_run)
    finally:
        engine.dispose()
    for op_id, why in report.skipped[:20]:
        print(f"  operation {op_id}: {why}")
    print(("dry run: " if args.dry_run else "") + report.summary())
    return 0


def cmd_backup(args) -> int:
    from service.storage.backup import backup

    settings = _settings(args)
    manifest = backup(settings, args.dest, progress=print)
    print(f"backup written to {args.dest}: {manifest['database']['kind']} database, "
          f"{manifest['captures']['files']} capture files ({manifest['captures']['bytes']} bytes)")
    return 0


def cmd_restore(args) -> int:
    from service.storage.backup import restore

    settings = _settings(args)
    manifest = restore(settings, args.src, force=args.force, progress=print)
    print(f"restored the backup of {manifest['created_at']} into {settings.data_dir}; "
          f"start the service with hvcb serve")
    return 0
