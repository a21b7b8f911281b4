"""``hvcb serve``, ``hvcb demo``, ``hvcb migrate``, ``hvcb key`` and ``hvcb worker``."""

from __future__ import annotations

import os
import shutil
import threading
import time


def register(sub) -> None:
    p = sub.add_parser("serve", help="run the monitoring service (REST API, fit workers)")
    p.add_argument("--host", default=None)
    p.add_argument("--port", type=int, default=None)
    p.add_argument("--config", default=None, help="settings TOML (default config/default.toml)")
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("demo", help="embedded demo: SQLite, scripted DAQ history (healthy, then an oil leak), API")
    p.add_argument("--host", default=None)
    p.add_argument("--port", type=int, default=None)
    p.add_argument("--config", default=None)
    p.add_argument("--keep", action="store_true", help="keep the previous demo database instead of starting fresh")
    p.add_argument("--interval", type=float, default=1.5, help="seconds between operations of the emulated DAQ")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("migrate", help="migrate the database (Alembic) up or down")
    p.add_argument("revision", nargs="?", default="head")
    p.add_argument("--down", action="store_true", help="downgrade to REVISION (default base)")
    p.add_argument("--config", default=None)
    p.set_defaults(func=cmd_migrate)

    p = sub.add_parser("key", help="create an API key (prints it once)")
    p.add_argument("name")
    p.add_argument("--role", choices=("agent", "reader", "operator", "admin"), default="reader",
                   help="agent: an edge agent's key, which may only upload captures")
    p.add_argument("--config", default=None)
    p.set_defaults(func=cmd_key)

    p = sub.add_parser("worker", help="run a Celery fit worker (needs HVCB_BROKER_URL and DATABASE_URL)")
    p.add_argument("--concurrency", type=int, default=1)
    p.add_argument("--config", default=None)
    p.set_defaults(func=cmd_worker)


def _settings(args, **overrides):
    from service.settings import command_settings

    return command_settings(args, **overrides)


def _migrate(settings) -> None:
    from service.storage.db import upgrade

    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.sqlalchemy_url)


def _print_key(settings):
    def show(key: str) -> None:
        print(f"Generated admin API key (shown once; also in {settings.key_file}, mode 0600):\n  {key}", flush=True)
    return show


def cmd_migrate(args) -> int:
    from service.storage.db import downgrade, upgrade

    settings = _settings(args)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    if args.down:
        downgrade(settings.sqlalchemy_url, "base" if args.revision == "head" else args.revision)
    else:
        upgrade(settings.sqlalchemy_url, args.revision)
    print(f"database {settings.sqlalchemy_url.split('@')[-1]} at {args.revision if not args.down else 'down'}")
    return 0


def _recovery(data_dir) -> str:
    """The command that prints a new admin key for the service whose data folder is ``data_dir``."""
    where = f"HVCB_DATA_DIR={data_dir}"
    if os.environ.get("HVCB_DEMO_DATABASE_URL"):  # the demo on another database (load benches)
        where += " HVCB_DATABASE_URL=$HVCB_DEMO_DATABASE_URL"
    return f"{where} hvcb key rescue --role admin"


def cmd_key(args) -> int:
    from service.storage import crud
    from service.storage.db import make_engine, session_factory

    settings = _settings(args)
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with session_factory(engine)() as session, session.begin():
            _, key = crud.create_api_key(session, name=args.name, role=args.role)
    finally:
        engine.dispose()
    print(key)
    return 0


def cmd_serve(args) -> int:
    import uvicorn

    from service.api.app import create_app

    settings = _settings(args, host=args.host, port=args.port)
    if settings.iec61850_port:
        from service.iec61850.server import preflight

        preflight(settings.iec61850_port)
    _migrate(settings)
    app = create_app(settings, on_key=_print_key(settings))
    print(f"hvcb serving on http://{settings.host}:{settings.port}/ (web page; API docs at /docs)", flush=True)
    from service.api.server import uvicorn_config

    uvicorn.Server(uvicorn_config(app, settings)).run()
    return 0


def cmd_worker(args) -> int:
    from service.cli import UserError
    from service.workers.celery_backend import make_celery_from_settings

    settings = _settings(args)
    if not settings.broker_url:
        raise UserError("hvcb worker needs HVCB_BROKER_URL (Celery with Redis)")
    app = make_celery_from_settings(settings)
    app.worker_main(["worker", "--loglevel=INFO", f"--concurrency={args.concurrency}", "--pool=prefork"])
    return 0


def cmd_demo(args) -> int:
    """The embedded demo: a Modbus TCP DAQ emulator on loopback plays the scripted history; the
    service listens to it through its real acquisition chain (driver → trigger → COMTRADE →
    ingest → fit job), on SQLite with the local process pool."""
    import uvicorn

    from service.api.app import create_app
    from service.api.demo import DemoDaq, DemoScript
    from service.breaker_file import load_breaker
    from service.cli import UserError

    base = _settings(args)
    if not base.breakers:
        raise UserError("the demo needs a breaker file in the settings (`breakers`)")
    demo_dir = base.data_dir / "demo"
    if demo_dir.exists() and not args.keep:
        shutil.rmtree(demo_dir)
    breaker = load_breaker(base.breakers[0])
    daq = DemoDaq(breaker, DemoScript(interval_s=args.interval))
    port = daq.start()
    acquisition = [{"driver": "modbus", "breaker": breaker.name,
                    "modbus": {"transport": "tcp", "host": "127.0.0.1", "port": port, "poll_interval_s": 0.2}}]
    try:
        # the demo's own SQLite file; HVCB_DEMO_DATABASE_URL (an empty database) for load benches on PostgreSQL
        # the demo's latch sticks (service/api/demo.py): its latch time is watched beside DO and BO
        alarms = {**base.alarms, "watched": {**(base.alarms.get("watched") or {"DO": "falling", "BO": "both"}),
                                             "latch_time_s": "rising"}}
        settings = _settings(args, host=args.host, port=args.port, data_dir=demo_dir,
                             database_url=os.environ.get("HVCB_DEMO_DATABASE_URL", ""),
                             broker_url="", executor="local", acquisition=acquisition, alarms=alarms)
        _migrate(settings)
        keys: list[str] = []  # the demo's fresh admin key, shown with the page's URL
        app = create_app(settings, on_key=keys.append)
        from service.api.server import uvicorn_config

        server = uvicorn.Server(uvicorn_config(app, settings))
        url = f"http://{settings.host}:{settings.port}"
        stop = threading.Event()

        def announce():
            while not server.started and not stop.is_set():
                time.sleep(0.1)
            if stop.is_set():
                return
            key = keys[0] if keys else settings.key_file.read_text().strip()
            print(f"\nhvcb demo: open {url}/ in a browser and sign in with this API key (admin):\n"
                  f"  {key}\n"
                  f"  (also in {settings.key_file}; API docs at {url}/docs)\n"
                  f"  DAQ: Modbus TCP emulator at 127.0.0.1:{port} playing the reference breaker's history\n"
                  f"  KEY=$(cat {settings.key_file})\n"
                  f"  curl -s -H \"X-API-Key: $KEY\" {url}/api/v1/breakers/1/health\n"
                  f"  curl -s -H \"X-API-Key: $KEY\" '{url}/api/v1/breakers/1/parameters?name=DO'\n"
                  f"  curl -s -H \"X-API-Key: $KEY\" '{url}/api/v1/alarms?state=active'\n"
                  f"  curl -s {url}/healthz\n"
                  f"Locked out (the admin key revoked or lost)? A new admin key, while this runs:\n"
                  f"  {_recovery(demo_dir)}\n"
                  f"The scripted history: healthy operations, then a buffer oil leak (DO falling). "
                  f"Fits appear within seconds; a DO alarm within about two minutes. Ctrl-C stops.\n", flush=True)
            while not stop.wait(1.0):
                if daq.done.is_set():
                    print(f"demo history complete: {daq.queued} operations played", flush=True)
                    return

        thread = threading.Thread(target=announce, name="hvcb-demo-announce", daemon=True)
        thread.start()
        try:
            server.run()
        finally:
            stop.set()
            thread.join(timeout=5)
    finally:
        daq.stop()
    return 0
