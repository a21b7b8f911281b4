"""Backup taken while the service runs and writes, restored to a new place: the restored service
answers the API exactly as the original did for everything the backup holds."""

from __future__ import annotations

import json
import threading
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from service.cli import main
from service.settings import load_settings
from service.storage.db import make_engine, session_factory, upgrade

from .conftest import temporary_pg_database
from .history import add_operation, build_history, synth_captures

ADMIN = "backup-test-admin-key-0123456789abcdef"


@pytest.fixture
def restore_url(empty_db_url, tmp_path):
    """Where the restore goes: a new SQLite file, or a new PostgreSQL database."""
    if empty_db_url.startswith("sqlite"):
        yield f"sqlite:///{tmp_path / 'restored' / 'data' / 'hvcb.sqlite3'}"
        return
    yield from temporary_pg_database("hvcb_restore")


def _config(path: Path, data_dir: Path, url: str) -> Path:
    path.write_text(f'data_dir = "{data_dir}"\ndatabase_url = "{url}"\nbreakers = []\n'
                    f'executor = "inline"\nbootstrap_admin_key = "{ADMIN}"\n')
    return path


class Writer(threading.Thread):
    """The service's write load: new operations of the control breaker, one after the other."""

    def __init__(self, url: str, capture_dir: Path, breaker_id: int):
        super().__init__(name="backup-test-writer", daemon=True)
        self.engine = make_engine(url)
        self.Session = session_factory(self.engine)
        self.capture_dir, self.breaker_id = capture_dir, breaker_id
        self.stop_flag = threading.Event()
        self.written: list[int] = []
        self.error: BaseException | None = None
        self.progress = threading.Condition()

    def run(self):
        cap = synth_captures()
        at = datetime(2026, 6, 1, tzinfo=timezone.utc)
        try:
            while not self.stop_flag.is_set():
                op = add_operation(self.Session, self.capture_dir, cap, breaker_id=self.breaker_id,
                                   key=f"live-{len(self.written):05d}", at=at + timedelta(hours=len(self.written)),
                                   do=41.0)
                with self.progress:
                    self.written.append(op)
                    self.progress.notify_all()
        except BaseException as exc:  # reported by the test
            self.error = exc
        finally:
            self.engine.dispose()

    def wait_for(self, n: int, timeout: float = 120.0) -> None:
        with self.progress:
            assert self.progress.wait_for(lambda: len(self.written) >= n or self.error, timeout), "writer stalled"
        assert self.error is None, f"writer failed: {self.error!r}"


def _api(settings, fn):
    from fastapi.testclient import TestClient

    from service.api.app import create_app

    app = create_app(settings, start_monitor=False, on_key=lambda k: None)
    with TestClient(app) as client:
        return fn(client)


def _answers(client, op_ids=None) -> dict:
    h = {"X-API-Key": ADMIN}

    def get(path):
        r = client.get(path, headers=h)
        assert r.status_code == 200, (path, r.text)
        return r.json()

    out = {"breakers": get("/api/v1/breakers"), "keys": get("/api/v1/keys"),
           "alarms": get("/api/v1/alarms?state=all")}
    ops = {}
    for b in out["breakers"]:
        for op in get(f"/api/v1/breakers/{b['id']}/operations?limit=1000"):
            ops[op["id"]] = op
        out[f"health {b['name']}"] = get(f"/api/v1/breakers/{b['id']}/health")
        out[f"DO {b['name']}"] = get(f"/api/v1/breakers/{b['id']}/parameters?name=DO")["points"]
    out["operations"] = ops
    out["curves"] = {i: get(f"/api/v1/operations/{i}/curve?points=200") for i in (op_ids or ops)}
    return out


def test_backup_during_writes_restores_to_the_same_api_answers(empty_db_url, restore_url, tmp_path):
    upgrade(empty_db_url)
    orig_dir = tmp_path / "orig" / "data"
    orig_cfg = _config(tmp_path / "orig.toml", orig_dir, empty_db_url)
    settings = load_settings(orig_cfg)
    engine = make_engine(empty_db_url)
    info = build_history(session_factory(engine), settings.capture_dir, n_per_breaker=24)
    engine.dispose()
    before = len(info["operations"])
    dest = tmp_path / "backup"

    def during(client):  # the original service runs while the backup is taken
        writer = Writer(empty_db_url, settings.capture_dir, info["breakers"]["control"])
        writer.start()
        try:
            writer.wait_for(2)
            assert main(["backup", str(dest), "--config", str(orig_cfg)]) == 0
            after_backup = len(writer.written)
            writer.wait_for(after_backup + 2)  # and the service goes on writing
        finally:
            writer.stop_flag.set()
            writer.join(60)
        assert writer.error is None
        return writer.written

    written = _api(settings, during)
    manifest = json.loads((dest / "manifest.json").read_text())
    assert manifest["captures"]["missing"] == []
    assert manifest["rows"]["revision"] is not None

    new_dir = tmp_path / "restored" / "data"
    new_cfg = _config(tmp_path / "restored.toml", new_dir, restore_url)
    assert main(["restore", str(dest), "--config", str(new_cfg)]) == 0
    assert main(["restore", str(dest), "--config", str(new_cfg)]) == 2, "a second restore must refuse to overwrite"
    restored = _api(load_settings(new_cfg), _answers)
    n = len(restored["operations"])
    assert before + 2 <= n < before + len(written), "the backup is not a snapshot taken during the writes"
    original = _api(settings, lambda c: _answers(c, op_ids=list(restored["operations"])))
    assert len(original["operations"]) == before + len(written)

    for key in ("breakers", "keys", "alarms", "curves", "health leaky", "DO leaky"):
        assert restored[key] == original[key], key
    assert restored["operations"] == {i: original["operations"][i] for i in restored["operations"]}
    kept = set(restored["operations"])
    assert restored["DO control"] == [p for p in original["DO control"] if p["operation_id"] in kept]
    assert any(a["state"] == "raised" for a in restored["alarms"]), "the history must hold an alarm"
    # the restored files are the restored service's own, not the original's
    assert all(str(Path(p).resolve()).startswith(str(new_dir.resolve()))
               for p in _capture_paths(restore_url))


def _capture_paths(url: str) -> list[str]:
    from sqlalchemy import select

    from service.storage.models import OperationRow

    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return list(conn.scalars(select(OperationRow.capture_path)))
    finally:
        engine.dispose()


def test_restore_refuses_a_damaged_or_unfinished_backup(tmp_path, capsys):
    cfg = _config(tmp_path / "r.toml", tmp_path / "data", f"sqlite:///{tmp_path / 'data' / 'x.sqlite3'}")
    (tmp_path / "half").mkdir()
    assert main(["restore", str(tmp_path / "half"), "--config", str(cfg)]) == 2
    assert "manifest.json is missing" in capsys.readouterr().err
    (tmp_path / "half" / "manifest.json").write_text(json.dumps(
        {"format": 1, "database": {"kind": "sqlite", "file": "hvcb.sqlite3", "sha256": "0" * 64}}))
    (tmp_path / "half" / "hvcb.sqlite3").write_bytes(b"not the database")
    assert main(["restore", str(tmp_path / "half"), "--config", str(cfg)]) == 2
    assert "does not match the manifest's checksum" in capsys.readouterr().err
    assert main(["backup", str(tmp_path / "half"), "--config", str(cfg)]) == 2
    assert "not empty" in capsys.readouterr().err
