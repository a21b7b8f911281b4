"""The OpenAPI document is the exact contract (docs/rest-api.md): every error status documented
with the one error body, public operations marked public, bodies that match, OPTIONS/Allow right,
and keys that cannot lock the service out."""

from __future__ import annotations

import pytest

from service.api.schemas import ErrorBody


def _operations(doc):
    for path, item in doc["paths"].items():
        for method, op in item.items():
            yield path, method, op


def test_the_last_admin_key_cannot_be_revoked_and_keeps_working(env):
    keys = env.client.get("/api/v1/keys", headers=env.h()).json()
    (admin,) = [k for k in keys if k["role"] == "admin"]
    r = env.client.delete(f"/api/v1/keys/{admin['id']}", headers=env.h())
    assert r.status_code == 409, r.text  # the last admin key, and the caller's own
    assert "cannot revoke itself" in r.json()["detail"] and "hvcb key" in r.json()["detail"]
    assert env.client.get("/api/v1/keys", headers=env.h()).status_code == 200  # still works

    second = env.client.post("/api/v1/keys", json={"name": "second admin", "role": "admin"}, headers=env.h()).json()
    own = env.client.delete(f"/api/v1/keys/{admin['id']}", headers=env.h())  # a key cannot revoke itself
    assert own.status_code == 409 and "cannot revoke itself" in own.json()["detail"]
    assert env.client.get("/api/v1/keys", headers=env.h()).status_code == 200
    other = {"X-API-Key": second["key"]}
    by_other = env.client.delete(f"/api/v1/keys/{admin['id']}", headers=other)  # another admin key does it
    assert by_other.status_code == 200 and by_other.json()["revoked_at"]
    assert env.client.get("/api/v1/keys", headers=env.h()).status_code == 401
    last = env.client.delete(f"/api/v1/keys/{second['id']}", headers=other)
    assert last.status_code == 409 and env.client.get("/api/v1/keys", headers=other).status_code == 200
    # the storage refuses the last active admin key whoever asks (a page, two admins at once)
    from service.storage import crud
    from service.storage.models import ApiKeyRow

    with env.Session() as s:
        with pytest.raises(crud.LastAdminKey):
            crud.revoke_api_key(s, row=s.get(ApiKeyRow, second["id"]))
    # revoking a reader key is not affected, and an already revoked admin key answers as it is
    reader = [k for k in keys if k["role"] == "reader"][0]
    assert env.client.delete(f"/api/v1/keys/{reader['id']}", headers=other).status_code == 200
    assert env.client.delete(f"/api/v1/keys/{admin['id']}", headers=other).status_code == 200


def test_every_operation_documents_every_error_with_the_one_error_body(env):
    doc = env.client.get("/openapi.json").json()
    schemas = doc["components"]["schemas"]
    assert "HTTPValidationError" not in schemas and "ErrorBody" in schemas
    seen = 0
    for path, method, op in _operations(doc):
        responses, where = op["responses"], f"{method.upper()} {path}"
        assert "503" in responses, where
        keyed = any(req for req in op["security"])
        if keyed:
            assert {"401", "403", "429"} <= set(responses), where
            assert "Retry-After" in responses["429"]["headers"], where
        if "requestBody" in op:
            assert {"400", "413", "422"} <= set(responses), where
        if any(p["in"] == "path" for p in op.get("parameters", [])):
            assert "404" in responses, where
        for status, entry in responses.items():
            if status[0] in "45":
                assert entry["content"]["application/json"]["schema"] == {"$ref": "#/components/schemas/ErrorBody"}, \
                    (where, status)
                assert entry["description"] not in ("Additional Response", "Validation Error"), (where, status)
        seen += 1
    assert seen >= 30
    ids = [op["operationId"] for _, _, op in _operations(doc)]
    assert len(set(ids)) == len(ids) and "list_breakers" in ids  # a generated client's function names
    health = doc["paths"]["/healthz"]["get"]
    assert {} in health["security"]  # public; a key is optional (it adds details)
    metrics = doc["paths"]["/metrics"]["get"]["responses"]
    assert "401" in metrics and "text/plain" in metrics["200"]["content"]
    keys = doc["paths"]["/api/v1/keys/{key_id}"]["delete"]["responses"]
    assert "409" in keys and "admin" in keys["409"]["description"]


def test_schema_and_server_agree_on_what_is_required(env):
    doc = env.client.get("/openapi.json").json()
    create = doc["components"]["schemas"]["BreakerCreate"]
    assert set(create["required"]) == {"breaker_file", "cam_table"}
    assert create["properties"]["cam_table"]["minLength"] == 1
    r = env.client.post("/api/v1/breakers", json={"breaker_file": "name = 'x'", "cam_table": ""}, headers=env.h())
    assert r.status_code == 422 and r.json()["errors"][0]["loc"] == ["cam_table"]
    upload = next(v for k, v in doc["components"]["schemas"].items() if k.startswith("Body_upload_capture"))
    assert upload["required"] == ["files"] and upload["properties"]["files"]["minItems"] == 1
    # form fields cannot be null, only left out: the schema offers no null
    assert "anyOf" not in upload["properties"]["operation"] and "anyOf" not in upload["properties"]["temperature_c"]


def test_a_validation_error_answers_the_error_body_in_words(env):
    r = env.client.post("/api/v1/keys", json={"name": "", "role": "root"}, headers=env.h())
    assert r.status_code == 422
    body = ErrorBody.model_validate(r.json())
    assert "name:" in body.detail and "role:" in body.detail
    assert {tuple(e.loc) for e in body.errors} == {("name",), ("role",)}


@pytest.mark.parametrize("payload", [b"\xff\xfe{", b"{not json"])
def test_a_malformed_body_answers_400_or_422_in_words_as_documented(env, payload):
    r = env.client.post("/api/v1/keys", content=payload, headers={**env.h(), "Content-Type": "application/json"})
    assert r.status_code in (400, 422), r.text
    body = ErrorBody.model_validate(r.json())
    assert "There was an error" not in body.detail and body.detail
    doc = env.client.get("/openapi.json").json()
    assert str(r.status_code) in doc["paths"]["/api/v1/keys"]["post"]["responses"]


def test_options_and_405_list_every_method_of_the_path(env):
    r = env.client.options("/api/v1/keys")
    assert r.status_code == 204
    assert {m.strip() for m in r.headers["allow"].split(",")} == {"GET", "HEAD", "POST", "OPTIONS"}
    r = env.client.patch("/api/v1/breakers/Q1/temperature", headers=env.h())
    assert r.status_code == 405 and {m.strip() for m in r.headers["allow"].split(",")} == {"GET", "HEAD", "PUT"}
    assert "PATCH" in ErrorBody.model_validate(r.json()).detail
    assert env.client.options("/api/v1/no-such-thing").status_code == 404


def test_the_recovery_command_the_demo_prints_makes_a_working_admin_key(tmp_path, monkeypatch):
    import os
    import shlex
    import subprocess
    import sys
    from pathlib import Path

    from service.api.commands import _recovery
    from service.storage import crud
    from service.storage.db import make_engine, session_factory, upgrade

    monkeypatch.delenv("HVCB_DEMO_DATABASE_URL", raising=False)
    data = tmp_path / "demo"
    data.mkdir()
    upgrade(f"sqlite:///{data / 'hvcb.sqlite3'}")
    words = shlex.split(_recovery(data))
    env_vars = dict(w.split("=", 1) for w in words if "=" in w and not w.startswith("-"))
    args = words[len(env_vars):]
    assert args[:2] == ["hvcb", "key"] and env_vars == {"HVCB_DATA_DIR": str(data)}
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-m", "service.cli", *args[1:]], capture_output=True, text=True,
                         timeout=120, cwd=root, env={**os.environ, **env_vars, "PYTHONPATH": str(root)})
    assert run.returncode == 0, run.stderr
    engine = make_engine(f"sqlite:///{data / 'hvcb.sqlite3'}")
    try:
        with session_factory(engine)() as s:
            row = crud.find_api_key(s, key=run.stdout.strip())
            assert row is not None and row.role == "admin"
    finally:
        engine.dispose()
