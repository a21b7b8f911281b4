"""Alembic migrations run up and down on SQLite and PostgreSQL."""

from sqlalchemy import inspect

from service.storage.db import downgrade, head_revision, make_engine, current_revision, upgrade

TABLES = {"breakers", "operations", "fits", "parameter_values", "alarms", "api_keys", "daq_status", "drift_states"}


def test_migrations_up_down_up(db_url):
    engine = make_engine(db_url)
    try:
        assert TABLES <= set(inspect(engine).get_table_names())
        assert current_revision(engine) == head_revision()
        downgrade(db_url, "base")
        engine.dispose()
        assert not (TABLES & set(inspect(engine).get_table_names()))
        assert current_revision(engine) is None
        upgrade(db_url)
        engine.dispose()
        assert TABLES <= set(inspect(engine).get_table_names())
    finally:
        engine.dispose()


def test_app_refuses_unmigrated_database(tmp_path):
    import pytest

    from service.storage.schema import NotMigrated, check_schema

    engine = make_engine(f"sqlite:///{tmp_path / 'empty.sqlite3'}")
    with pytest.raises(NotMigrated, match="hvcb migrate"):
        check_schema(engine)
    engine.dispose()
