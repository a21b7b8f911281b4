"""schemathesis (the dev extra's CLI) with every check against the live app: the OpenAPI document
is the exact contract (docs/rest-api.md). 0 failures expected.

The app runs under uvicorn on a loopback port on SQLite with the reference breaker, a demo-like
history (40 fits, DO falling, the DO alarm raised) and its generated admin key, the only admin
key; the CLI runs deterministically (no seed to vary, no example database), 30 examples per
operation, every phase (coverage, fuzzing, stateful). Wrong keys are not throttled here (as in
every service test; tests/security/test_d07_throttle.py tests the throttle): against `hvcb demo`
schemathesis's wrong-key probes trip it (docs/rest-api.md, "The contract, tested").

It must not lock itself out: it may create admin keys and revoke any other key, but
``DELETE /keys/{its own id}`` answers 409 (a key cannot revoke itself). The key works at the end.
"""

from __future__ import annotations

import json
import subprocess
import sys
from types import SimpleNamespace

import pytest

from conftest import BREAKER_FILE, make_settings
from test_alarm_lifecycle import _leak
from tests.live_server import LiveServer

pytest.importorskip("schemathesis")

EXAMPLES_PER_OPERATION = 30
# Some operations check content that JSON Schema cannot describe: a breaker file must be TOML
# that builds a breaker, an upload must be a readable capture, a breaker diagnosis needs
# stored operations, a report's or an export's window needs `from` before `to`, and maintenance
# cannot be logged as done in the future or before 1970. A schema-valid request may be refused there with 422 in words; every other
# operation must accept what its schema allows.
# 410 is a state like 404: the operation exists, its raw capture was pruned by retention (here:
# the history's fits have no capture file), so a schema-valid curve request may answer it.
CONFIG = """
[checks.positive_data_acceptance]
expected-statuses = ["2xx", "3xx", "401", "403", "404", "409", "410", "429"]

[[operations]]
include-operation-id = ["create_breaker", "upload_capture", "request_breaker_diagnosis", "breaker_report", "request_report",
                        "operations_csv", "alarms_csv", "post_maintenance"]
checks.positive_data_acceptance.expected-statuses = ["2xx", "401", "403", "404", "409", "410", "422", "429"]
"""


@pytest.fixture
def live_app(tmp_path):
    from service.api.app import create_app
    from service.storage.db import upgrade

    url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    (tmp_path / "data").mkdir()
    upgrade(url)
    shown = []
    settings = make_settings(tmp_path, url, breakers=[str(BREAKER_FILE)])
    app = create_app(settings, on_key=shown.append)
    with LiveServer(app, name="uvicorn-schemathesis") as server:
        # as in the demo: a history of fits with DO falling, and the drift job's DO alarm raised
        _leak(SimpleNamespace(Session=app.state.Session, settings=settings))
        yield app, server.url, shown[0]


def schemathesis_run(base_url: str, key: str, where, *selection: str) -> dict:
    """Run the CLI with every check; its JSON report."""
    (where / "schemathesis.toml").write_text(CONFIG)
    cmd = [sys.executable, "-m", "schemathesis.cli", "--config-file", str(where / "schemathesis.toml"), "run",
           f"{base_url}/openapi.json", "--checks", "all", "--max-examples", str(EXAMPLES_PER_OPERATION),
           "--generation-deterministic", "--workers", "1", "--header", f"X-API-Key: {key}", "--no-color",
           "--request-timeout", "30", "--report", "json", "--report-json-path", str(where / "report.json"),
           *selection]
    run = subprocess.run(cmd, cwd=where, capture_output=True, text=True, timeout=600)
    assert (where / "report.json").exists(), run.stdout[-3000:] + run.stderr[-3000:]
    report = json.loads((where / "report.json").read_text())
    report["output"] = run.stdout
    return report


def _failures(report: dict) -> str:
    out = report["output"]
    return out[out.find("FAILURES"):][:6000] if "FAILURES" in out else json.dumps(report["failures"])[:3000]


def test_schemathesis_all_checks_find_nothing(live_app, tmp_path):
    import httpx

    from service.storage import crud

    app, base_url, key = live_app
    report = schemathesis_run(base_url, key, tmp_path)
    assert report["operations"]["tested"] >= 30 and report["test_cases"]["generated"] >= 30 * 20
    assert report["test_cases"]["unique_failures"] == 0 and not report["errors"], _failures(report)
    assert not report["warnings"].get("missing_auth"), report["warnings"]  # the key worked throughout
    with app.state.Session() as s:
        assert crud.find_api_key(s, key=key) is not None  # never revoked: DELETE of it answers 409
    assert httpx.get(f"{base_url}/api/v1/keys", headers={"X-API-Key": key}, timeout=10).status_code == 200
    print(f"schemathesis: {report['test_cases']['generated']} cases, {report['test_cases']['unique_failures']} failures")
