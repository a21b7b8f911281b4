"""A service with a 10,000-operation history of the reference breaker, built once per module in
bulk (tests/reports/history.py), on SQLite, with the app under a TestClient."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
BREAKER_FILE = REPO / "config" / "breakers" / "reference-252kV.toml"
N_HISTORY = 10_000


@pytest.fixture(scope="module")
def service10k(tmp_path_factory):
    """(app, client, keys, settings, url, history) of a service holding 10,000 operations whose
    latest opening points at a real capture (the report's curve)."""
    from fastapi.testclient import TestClient

    from drivers.synthetic import synthesize_capture
    from service.acquisition.comtrade_writer import write_comtrade
    from service.api.app import create_app
    from service.breaker_file import load_breaker
    from service.settings import load_settings
    from service.storage import crud
    from service.storage.db import upgrade

    from .history import bulk_history

    data = tmp_path_factory.mktemp("reports10k") / "data"
    data.mkdir()
    url = f"sqlite:///{data / 'hvcb.sqlite3'}"
    upgrade(url)
    settings = load_settings(data_dir=data, database_url=url, broker_url="", executor="inline",
                             bootstrap_admin_key=None, breakers=[str(BREAKER_FILE)])
    breaker = load_breaker(BREAKER_FILE)
    cap, _ = synthesize_capture(breaker, "open", dict(breaker.design_parameters()), rng=np.random.default_rng(1))
    cfg = write_comtrade(cap, data / "captures", "latest-opening")
    shown = []
    app = create_app(settings, on_key=shown.append)
    with TestClient(app) as client:
        keys = {"admin": shown[0]}
        with app.state.Session() as s, s.begin():
            keys["reader"] = crud.create_api_key(s, name="reports-reader", role="reader")[1]
        history = bulk_history(app.state.Session, settings.drift_settings, breaker, capture_path=str(cfg),
                               n=N_HISTORY)
        yield SimpleNamespace(app=app, client=client, keys=keys, settings=settings, url=url, data=data,
                              history=history, Session=app.state.Session,
                              h=lambda role="reader": {"X-API-Key": keys[role]})
