"""D8: the data folder and its folders are 0700 and its files 0600, whatever the umask."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from .conftest import comtrade_pair, synth


@pytest.fixture
def loose_umask():
    old = os.umask(0o022)
    yield
    os.umask(old)


def test_files_are_private_under_umask_022(loose_umask, tmp_path, breaker):
    from fastapi.testclient import TestClient

    from service.api.app import create_app

    from .conftest import make_settings

    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    from service.storage.db import upgrade

    upgrade(url)  # `hvcb migrate` under the loose umask creates the file
    settings = make_settings(tmp_path, url)
    shown = []
    app = create_app(settings, on_key=shown.append)
    cfg, dat = comtrade_pair(synth(breaker, "open", seed=8))
    with TestClient(app) as client:
        r = client.post("/api/v1/breakers/1/captures", headers={"X-API-Key": shown[0]},
                        files=[("files", ("a.cfg", cfg)), ("files", ("a.dat", dat))])
        assert r.status_code == 202, r.text
        data = Path(settings.data_dir)
        found = list(data.rglob("*"))
        assert any(p.suffix == ".cfg" for p in found) and (data / "hvcb.sqlite3-wal").exists()
        for p in [data, *found]:
            mode = stat.S_IMODE(p.stat().st_mode)
            want = 0o700 if p.is_dir() else 0o600
            assert mode & 0o077 == 0, f"{p.relative_to(tmp_path)} is {oct(mode)}, want {oct(want)}"
