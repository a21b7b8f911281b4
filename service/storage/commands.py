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

    p = sub.add_parser("commission", help="record a close–open pair as a breaker's commissioning pair "
                                          "(its spring setting's reference, docs/pairs.md)")
    p.add_argument("breaker", help="breaker name, tag or id")
    p.add_argument("--operation", type=int, required=True, help="either half of the close–open pair (operation id)")
    p.add_argument("--steps", type=float, required=True,
                   help="the nut setting it was recorded at [steps from the design seat]")
    p.add_argument("--by", default="cli", help="who records it (kept with the reference)")
    p.add_argument("--config", default=None)
    p.set_defaults(func=cmd_commission)


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


def cmd_commission(args) -> int:
    from sqlalchemy import or_, select

    from service.errors import UserError
    from service.storage import crud
    from service.storage.db import make_engine, session_factory
    from service.storage.models import BreakerRow
    from service.storage.schema import check_schema
    from service.storage.spring_references import NoPair, record_reference

    settings = _settings(args)
    engine = make_engine(settings.sqlalchemy_url)
    try:
        check_schema(engine)
        with session_factory(engine)() as session, session.begin():
            ref = str(args.breaker)
            b = session.scalar(select(BreakerRow).where(or_(BreakerRow.name == ref, BreakerRow.tag == ref)))
            if b is None and ref.isdigit():
                b = session.get(BreakerRow, int(ref))
            if b is None:
                raise UserError(f"no breaker named {ref!r}")
            op = crud.get_operation(session, operation_id=args.operation)
            if op is None or op.breaker_id != b.id:
                raise UserError(f"operation {args.operation} is not one of {b.name}'s")
            try:
                row = record_reference(session, op, crud.breaker_model(b), known_steps=args.steps, by=args.by)
            except (NoPair, ValueError) as exc:
                raise UserError(str(exc)) from None
            r = row.reading
            print(f"{b.name}: commissioning pair closing {row.closing_id} / opening {row.opening_id} at "
                  f"{row.known_steps:+g} nut steps (the pair reads {r['steps']:+.2f} ± {r['sd_steps']:.2f} "
                  f"steps from the design seat; offset {r['steps'] - row.known_steps:+.2f} steps removed "
                  "from its later pairs)")
    finally:
        engine.dispose()
    return 0
