"""SQL storage: models, engine/session factory, migrations and keyword-only CRUD functions."""
