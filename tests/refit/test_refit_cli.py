"""``hvcb refit`` bad input: one sentence and exit code 2, never a traceback."""

import pytest

from service.cli import main


@pytest.fixture
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HVCB_DATA_DIR", str(tmp_path))
    monkeypatch.delenv("DATABASE_URL", raising=False)
    monkeypatch.delenv("HVCB_DATABASE_URL", raising=False)
    return tmp_path


def test_unmigrated_database_says_run_migrate(data_dir, capsys):
    assert main(["refit"]) == 2
    err = capsys.readouterr().err
    assert "hvcb refit: error: database" in err and "run `hvcb migrate`" in err
    assert "Traceback" not in err


def test_bad_date_and_unknown_breaker(data_dir, capsys):
    assert main(["refit", "--since", "31/01/2026"]) == 2
    assert "--since '31/01/2026' is not a date" in capsys.readouterr().err
    assert main(["migrate"]) == 0
    capsys.readouterr()
    assert main(["refit", "--breaker", "nope"]) == 2
    assert "no breaker named 'nope'" in capsys.readouterr().err


def test_empty_history_is_a_finished_run(data_dir, capsys):
    assert main(["migrate"]) == 0
    assert main(["refit", "--backend", "inline"]) == 0
    out = capsys.readouterr().out
    assert "refit run 1: 0 operations" in out and "0 re-fitted" in out
