"""A SCADA integrator's typed client, generated from the service's own /openapi.json with
openapi-python-client (the dev extra's), reads the fleet, a breaker's parameters, its alarms and
a diagnosis, and gets the documented error body for what it asks wrongly.

The data is real: fits stored through the storage functions and the drift job raising the DO
alarm (as tests/service/test_alarm_lifecycle.py does), the diagnosis queued and run by the
service's own runner. Generation runs offline, in a temp folder.
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from test_alarm_lifecycle import _leak

pytest.importorskip("openapi_python_client")


@pytest.fixture
def hvcb_client(env, tmp_path):
    """The generated package ``hvcb_client``, imported from ``tmp_path``."""
    spec = tmp_path / "openapi.json"
    spec.write_text(json.dumps(env.client.get("/openapi.json").json()))
    bin_dir = str(Path(sys.executable).parent)  # its formatter (ruff) is installed beside it
    # the condition report is a binary download: the generator reads files as application/octet-stream
    config = tmp_path / "generator.json"
    config.write_text(json.dumps({"content_type_overrides": {"application/pdf": "application/octet-stream"}}))
    run = subprocess.run([sys.executable, "-m", "openapi_python_client", "generate", "--path", str(spec),
                          "--meta", "none", "--config", str(config),
                          "--output-path", str(tmp_path / "hvcb_client")],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path,
                         env={**os.environ, "PATH": bin_dir + os.pathsep + os.environ.get("PATH", "")})
    assert run.returncode == 0, run.stdout + run.stderr
    # a spec the generator cannot fully follow gives a warning and leaves pieces out
    assert "Warning" not in run.stdout + run.stderr, run.stdout + run.stderr
    sys.path.insert(0, str(tmp_path))
    try:
        yield importlib.import_module("hvcb_client")
    finally:
        sys.path.remove(str(tmp_path))
        for name in [m for m in sys.modules if m == "hvcb_client" or m.startswith("hvcb_client.")]:
            del sys.modules[name]


def test_a_generated_client_reads_fleet_parameters_alarms_and_a_diagnosis(env, hvcb_client):
    from hvcb_client import AuthenticatedClient
    from hvcb_client.api.alarms import alarm_history, list_alarms
    from hvcb_client.api.breakers import get_breaker, list_breakers, parameter_trend
    from hvcb_client.api.operations import get_diagnosis
    from hvcb_client.models import (AlarmPublic, BreakerPublic, DiagnosisPublic, ErrorBody, ParameterTrendName,
                                    TrendPublic)

    _leak(env)  # 40 openings, DO falling 2 %/operation from the 25th: the drift job raises the DO alarm
    client = AuthenticatedClient(base_url="http://testserver", token=env.keys["reader"], prefix="",
                                 auth_header_name="X-API-Key")
    # the app in process, through every middleware; a given httpx client carries its own headers
    env.client.headers["X-API-Key"] = env.keys["reader"]
    client.set_httpx_client(env.client)

    fleet = list_breakers.sync(client=client)
    assert [type(b) for b in fleet] == [BreakerPublic] and fleet[0].name == "reference-252kV"
    breaker_id = fleet[0].id

    trend = parameter_trend.sync(client=client, breaker_id=breaker_id, name=ParameterTrendName.DO)
    assert isinstance(trend, TrendPublic) and trend.unit == "s^-1" and len(trend.points) == 40
    assert trend.points[-1].value < 0.8 * trend.points[0].value  # the leak, as stored

    alarms = list_alarms.sync(client=client, breaker_id=breaker_id)
    assert alarms and all(isinstance(a, AlarmPublic) for a in alarms)
    assert {a.parameter for a in alarms} == {"DO"} and alarms[0].raised_at.tzinfo is not None
    history = alarm_history.sync(client=client, breaker_id=breaker_id)
    assert history[0].alarm.id == min(a.id for a in alarms) and history[0].first_out

    op = trend.points[-1].operation_id
    first = get_diagnosis.sync_detailed(client=client, operation_id=op)
    assert first.status_code == 202 and isinstance(first.parsed, DiagnosisPublic)
    deadline = time.monotonic() + 120
    diagnosis = first.parsed
    while diagnosis.status in ("queued", "running") and time.monotonic() < deadline:
        time.sleep(0.5)
        diagnosis = get_diagnosis.sync(client=client, operation_id=op)
    # these operations have no raw capture on disk: the diagnosis fails, and says why in words
    assert diagnosis.status == "failed" and diagnosis.failure_reason, diagnosis
    assert diagnosis.operation_id == op and diagnosis.finished_at is not None

    missing = get_breaker.sync_detailed(client=client, breaker_id=breaker_id + 1000)
    assert missing.status_code == 404 and isinstance(missing.parsed, ErrorBody)
    assert "no breaker" in missing.parsed.detail
    env.client.headers["X-API-Key"] = "hvcb_wrong"
    refused = list_breakers.sync_detailed(client=client)
    assert refused.status_code == 401 and isinstance(refused.parsed, ErrorBody)
