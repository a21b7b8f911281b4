"""Security regression fixtures (issue 25): the service fixtures (a real database per test,
SQLite always and PostgreSQL on its lane) and a live uvicorn server for tests that need real
sockets (timeouts, bodies announced but not sent, concurrency)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("hvcb_service_fixtures",
                                               Path(__file__).resolve().parents[1] / "service" / "conftest.py")
svc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(svc)

pg_server, db_url, env, breaker = svc.pg_server, svc.db_url, svc.env, svc.breaker
BREAKER_FILE, make_settings, synth, Env = svc.BREAKER_FILE, svc.make_settings, svc.synth, svc.Env


class Live:
    """A service on 127.0.0.1 served by uvicorn (with hvcb's protocol and limits) in a thread."""

    def __init__(self, app, settings, keys, served):
        self.app, self.settings, self.keys, self.served = app, settings, keys, served
        self.base = f"http://127.0.0.1:{settings.port}"
        self.port = settings.port

    def h(self, role="admin"):
        return {"X-API-Key": self.keys[role]}


@pytest.fixture
def live_server(tmp_path, db_url):
    """live_server(**settings) -> Live; ``routes(app)`` may add test-only routes before start."""
    from service.api.app import create_app
    from service.api.server import uvicorn_config
    from service.storage import crud
    from tests.live_server import LiveServer, free_port

    started = []

    def start(routes=None, **overrides):
        settings = make_settings(tmp_path, db_url, port=free_port(), breakers=[BREAKER_FILE], **overrides)
        shown = []
        app = create_app(settings, on_key=shown.append)
        if routes is not None:
            routes(app)
        served = LiveServer(app, port=settings.port, name="test-uvicorn",
                            config=lambda app, port: uvicorn_config(app, settings))
        started.append(served.start(timeout_s=30))
        keys = {"admin": shown[0]}
        with app.state.Session() as s, s.begin():
            for role in ("reader", "operator", "agent"):
                keys[role] = crud.create_api_key(s, name=f"test-{role}", role=role)[1]
        return Live(app, settings, keys, served)

    yield start
    for served in started:
        served.stop()


def comtrade_pair(capture, *, travel="travel", vibration="vibration") -> tuple[bytes, bytes]:
    """(cfg, dat) bytes of ``capture`` as COMTRADE, its channels renamed as given."""
    import tempfile

    from service.acquisition.comtrade_writer import write_comtrade

    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(write_comtrade(capture, tmp, "cap", format="ASCII"))
        text = cfg.read_text()
        text = text.replace(",travel,", f",{travel},").replace(",vibration,", f",{vibration},")
        return text.encode(), cfg.with_suffix(".dat").read_bytes()


def sqlite_url(tmp_path) -> str:
    """A migrated SQLite database, for modules whose finding does not depend on the database
    (they override ``db_url`` with it; the pool, clock and path findings run on both lanes)."""
    from service.storage.db import upgrade

    (tmp_path / "data").mkdir(exist_ok=True)
    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    upgrade(url)
    return url
