"""Capture uploads go through the same COMTRADE reader as ``hvcb fit``/``inspect``: field quirks
are accepted, and a refusal is a 4xx with the reader's own message that leaves nothing behind."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from sqlalchemy import func, select

from drivers.capture import CaptureError
from drivers.capture_file import read_capture
from service.storage.models import FitRow, OperationRow

from comtrade_bytes import comtrade_pair
from conftest import synth

URL = "/api/v1/breakers/1/captures"
EXCEPTION_NAME = re.compile(r"\b\w*(Error|Exception)\b|Traceback|codec can't")


def _state(env):
    data = Path(env.settings.data_dir)
    with env.Session() as s:
        return (s.scalar(select(func.count()).select_from(OperationRow)),
                s.scalar(select(func.count()).select_from(FitRow)),
                sorted(str(p) for p in data.rglob("*") if p.is_file() and p.suffix not in (".db", ".db-journal",
                                                                                          ".db-wal", ".db-shm")))


def _field_style(cfg: bytes, dat: bytes) -> tuple[bytes, bytes]:
    """The same record as a Russian relay writes it: cp1251 station, CRLF, a blank line after each row."""
    cfg = cfg.replace(b"hvcb-test", "Подстанция".encode("cp1251")).replace(b"\n", b"\r\n")
    dat = b"".join(row + b",\r\n\r\n" for row in dat.splitlines()) + b"\x1a"
    return cfg, dat


def test_a_field_style_pair_and_a_cff_are_accepted(env, breaker):
    cfg, dat = _field_style(*comtrade_pair(synth(breaker, "open", 11)))
    r = env.client.post(URL, headers=env.h("operator"), files=[("files", ("A.CFG", cfg)), ("files", ("A.DAT", dat))])
    assert r.status_code == 202, r.text
    assert r.json()["operation"] == "open"
    cff = b"--- file type: CFG ---\r\n" + cfg + b"--- file type: DAT ASCII ---\r\n" + dat
    r = env.client.post(URL, headers=env.h("operator"), files=[("files", ("b.cff", cff))])
    assert r.status_code == 202, r.text


@pytest.mark.parametrize("case", ["bad_counts", "truncated_to_nothing", "gbk_no_travel", "short_row"])
def test_refused_uploads_carry_the_readers_message_and_leave_nothing(env, breaker, tmp_path, case):
    cfg, dat = comtrade_pair(synth(breaker, "open", 12))
    if case == "bad_counts":
        cfg = cfg.replace(b"2,2A,0D", b"2,2 analog,0D")
    elif case == "truncated_to_nothing":
        dat = b"\x1a"
    elif case == "gbk_no_travel":
        cfg = cfg.replace(b"travel", "行程".encode("gbk"))
    elif case == "short_row":
        rows = dat.splitlines()
        rows[5] = b"6,500"
        dat = b"\n".join(rows)
    (tmp_path / "x.cfg").write_bytes(cfg)
    (tmp_path / "x.dat").write_bytes(dat)
    with pytest.raises(CaptureError) as local:
        read_capture(tmp_path / "x.cfg")
    expected = str(local.value).replace(str(tmp_path) + "/", "").replace("upload:", "")
    before = _state(env)
    r = env.client.post(URL, headers=env.h("operator"), files=[("files", ("x.cfg", cfg)), ("files", ("x.dat", dat))])
    assert 400 <= r.status_code < 500, r.text
    detail = r.json()["detail"]
    assert detail.replace("upload:", "") == expected
    assert "x.cfg" in detail or "x.dat" in detail
    assert not EXCEPTION_NAME.search(detail)
    assert _state(env) == before
