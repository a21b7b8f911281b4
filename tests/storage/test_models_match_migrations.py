"""The ORM models (service/storage/models.py) and the migrations describe the same schema.

A database migrated to head is compared with the models' metadata by Alembic's autogenerate
(``compare_metadata``): a column, index, constraint or type present on one side only is a diff.
SQLite always; PostgreSQL when HVCB_TEST_POSTGRES_URL is set (the ``empty_db_url`` fixture).
"""

from __future__ import annotations

from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import Column, Integer, MetaData

from service.storage.db import make_engine, upgrade
from service.storage.models import Base


def schema_diff(url: str, metadata=Base.metadata) -> list:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            context = MigrationContext.configure(conn, opts={"compare_type": True})
            return compare_metadata(context, metadata)
    finally:
        engine.dispose()


def test_models_match_a_freshly_migrated_database(empty_db_url):
    upgrade(empty_db_url)
    diff = schema_diff(empty_db_url)
    assert diff == [], "the models and the migrations differ (add a migration or fix models.py):\n" + \
        "\n".join(map(str, diff))


def test_a_column_missing_from_the_migrations_is_found(empty_db_url):
    """The comparison is not vacuous: a column only the models have is reported."""
    upgrade(empty_db_url)
    metadata = MetaData()
    for table in Base.metadata.tables.values():
        table.to_metadata(metadata)  # a copy: the models' own metadata stays untouched
    metadata.tables["breakers"].append_column(Column("not_in_any_migration", Integer, nullable=True))
    diff = schema_diff(empty_db_url, metadata)
    assert any(d[0] == "add_column" and d[3].name == "not_in_any_migration" for d in diff), diff
