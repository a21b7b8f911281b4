"""docker/: the compose file has the scaled-out shape and names commands the project provides.

Docker cannot run here; this checks the files against the project instead.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import pytest

yaml = pytest.importorskip("yaml")

ROOT = Path(__file__).resolve().parents[1]
COMPOSE = yaml.safe_load((ROOT / "docker" / "compose.yaml").read_text())
SERVICES = COMPOSE["services"]


def test_four_services_with_postgres_and_redis_healthchecks():
    assert set(SERVICES) == {"api", "worker", "postgres", "redis"}
    assert SERVICES["postgres"]["image"] == "postgres:16"
    assert SERVICES["redis"]["image"] == "redis:7"
    assert "pg_isready" in " ".join(SERVICES["postgres"]["healthcheck"]["test"])
    for name in ("api", "worker"):
        assert SERVICES[name]["depends_on"]["postgres"]["condition"] == "service_healthy"


def test_api_and_worker_share_settings_and_the_data_volume():
    for name in ("api", "worker"):
        env = SERVICES[name]["environment"]
        assert env["DATABASE_URL"] == ("postgresql+psycopg://hvcb:${HVCB_DB_PASSWORD:?set HVCB_DB_PASSWORD}"
                                       "@postgres:5432/hvcb")
        assert env["HVCB_BROKER_URL"] == "redis://redis:6379/0"
        assert env["HVCB_DATA_DIR"] == "/data"
        assert "hvcb-data:/data" in SERVICES[name]["volumes"]
    assert "hvcb-data" in COMPOSE["volumes"]


def test_commands_exist_in_the_project():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    api = SERVICES["api"]["command"]
    assert api[:2] == ["hvcb", "serve"] and scripts["hvcb"] == "service.cli:main"
    assert "service.api.commands" in (ROOT / "service" / "cli.py").read_text()  # registers serve

    worker = SERVICES["worker"]["command"]
    assert worker[:3] == ["celery", "-A", "service.workers.celery_app"] and "worker" in worker
    dependencies = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert any(d.startswith("celery") for d in dependencies)


def test_celery_app_module_is_where_the_worker_command_looks(tmp_path):
    # `celery -A service.workers.celery_app worker` needs a Celery application named `app` there,
    # built from the settings at import (in a child: the import reads the environment).
    import subprocess
    import sys

    module_name = SERVICES["worker"]["command"][2]
    env = dict(os.environ, HVCB_BROKER_URL="redis://127.0.0.1:1/0", HVCB_DATA_DIR=str(tmp_path),
               DATABASE_URL=f"sqlite:///{tmp_path / 'hvcb.sqlite3'}")
    code = (f"import celery, importlib; m = importlib.import_module({module_name!r}); "
            "assert isinstance(m.app, celery.Celery), type(m.app); print(m.app.main or 'app')")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr


def test_dockerfile_installs_the_project_and_serves():
    text = (ROOT / "docker" / "Dockerfile").read_text()
    assert text.startswith("#") and "FROM python:3.11-slim" in text
    assert "pip install ." in text
    assert 'CMD ["hvcb", "serve"' in text
    for path in ("pyproject.toml", "service", "drivers", "config", "migrations", "alembic.ini"):
        assert (ROOT / path).exists() and f"COPY {path}" in text


def test_no_database_password_ships_and_the_service_accepts_the_compose_url():
    """compose interpolates the password; the settings must accept a strong one and refuse 'hvcb'."""
    import pydantic

    from service.settings import Settings

    assert "${HVCB_DB_PASSWORD" in SERVICES["postgres"]["environment"]["POSTGRES_PASSWORD"]
    url = SERVICES["api"]["environment"]["DATABASE_URL"]
    strong = url.replace("${HVCB_DB_PASSWORD:?set HVCB_DB_PASSWORD}", "V3ry-l0ng-and-r4ndom-pw")
    assert Settings(database_url=strong).database_url == strong
    with pytest.raises(pydantic.ValidationError):
        Settings(database_url=url.replace("${HVCB_DB_PASSWORD:?set HVCB_DB_PASSWORD}", "hvcb"))
