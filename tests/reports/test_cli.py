"""``hvcb report``'s refusals are one line in words and exit 2, never a traceback."""

from __future__ import annotations

import pytest

from service.cli import main

from .conftest import BREAKER_FILE


@pytest.fixture
def database(tmp_path, monkeypatch):
    from service.storage import crud
    from service.storage.db import make_engine, session_factory, upgrade

    url = f"sqlite:///{tmp_path / 'hvcb.sqlite3'}"
    upgrade(url)
    engine = make_engine(url)
    with session_factory(engine)() as s, s.begin():
        crud.register_breaker_file(s, path=BREAKER_FILE, tag="Q1")
    engine.dispose()
    monkeypatch.setenv("DATABASE_URL", url)
    monkeypatch.setenv("HVCB_DATA_DIR", str(tmp_path))
    # No service to ask (a port nothing listens on): the report is drawn here, from this database.
    from tests.live_server import free_port

    monkeypatch.setenv("HVCB_URL", f"http://127.0.0.1:{free_port()}")
    return url


@pytest.mark.parametrize("args, words", [
    (["--from", "yesterday"], "--from 'yesterday' is not a time (use ISO 8601"),
    (["--from", "2026-02-01", "--to", "2026-01-01"], "is after its end"),
    (["-o", "/nonexistent-folder/r.pdf"], "the folder /nonexistent-folder does not exist"),
])
def test_bad_arguments_are_refused_before_the_database_is_read(args, words, tmp_path, capsys):
    argv = ["report", "reference-252kV", "-o", str(tmp_path / "r.pdf"), *args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("hvcb report: error: ") and words in err and "Traceback" not in err
    assert not (tmp_path / "r.pdf").exists()


def test_an_unknown_breaker_names_the_known_ones(database, tmp_path, capsys):
    assert main(["report", "Q9", "-o", str(tmp_path / "r.pdf")]) == 2
    err = capsys.readouterr().err
    assert "no breaker named, tagged or numbered 'Q9' (breakers: reference-252kV)" in err


def test_a_breaker_without_operations_gets_a_report_that_says_so(database, tmp_path, capsys):
    import shutil
    import subprocess

    if shutil.which("pdftotext") is None:
        pytest.skip("report lane off: poppler-utils (pdftotext) not installed")
    out = tmp_path / "empty.pdf"
    assert main(["report", "Q1", "-o", str(out)]) == 0  # by its tag
    assert f"wrote {out}" in capsys.readouterr().out
    text = subprocess.run(["pdftotext", "-raw", str(out), "-"], capture_output=True, text=True).stdout
    assert "0 openings and 0 closings" in text and "No fitted opening in the whole stored history" in text
    assert "No alarm raised" in text


def test_an_unmigrated_database_says_what_to_run(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DATABASE_URL", f"sqlite:///{tmp_path / 'empty.sqlite3'}")
    monkeypatch.setenv("HVCB_DATA_DIR", str(tmp_path))
    assert main(["report", "x", "-o", str(tmp_path / "r.pdf")]) == 2
    assert "run `hvcb migrate`" in capsys.readouterr().err
