"""The Prometheus alerting rules shipped beside the compose file (docker/prometheus/alerts.yml):
valid for promtool, firing as their unit tests say (docker/prometheus/alerts.test.yml), and
written against metrics the service's /metrics really exposes. The promtool lane runs where
Debian's `prometheus` package is installed (.ci/run installs it) and says why it skips otherwise."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import make_settings, running_app

ROOT = Path(__file__).resolve().parents[2]
RULES = ROOT / "docker" / "prometheus" / "alerts.yml"
RULE_TESTS = ROOT / "docker" / "prometheus" / "alerts.test.yml"


@pytest.fixture
def promtool() -> str:
    path = shutil.which("promtool")
    if path is None:
        pytest.skip("Prometheus rules lane off: promtool is not installed (apt-get install prometheus)")
    return path


def test_promtool_checks_the_rules(promtool):
    r = subprocess.run([promtool, "check", "rules", str(RULES)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "SUCCESS: 11 rules found" in r.stdout


def test_the_rules_fire_as_their_unit_tests_say(promtool):
    r = subprocess.run([promtool, "test", "rules", str(RULE_TESTS)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr


def test_every_metric_the_rules_use_is_exposed_by_the_service(tmp_path):
    import yaml

    exprs = [rule["expr"] for group in yaml.safe_load(RULES.read_text())["groups"] for rule in group["rules"]]
    used = {m for e in exprs for m in re.findall(r"\b(hvcb_[a-z_]+)", e)}
    assert {"hvcb_alarm_active", "hvcb_daq_down", "hvcb_queue_depth"} <= used
    settings = make_settings(tmp_path, f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}", notifications={
        "routes": [{"name": "hook", "kind": "webhook", "url": "http://127.0.0.1:9/x", "secret": "s" * 20}]},
        acquisition={"driver": "modbus", "modbus": {"host": "127.0.0.1", "port": 9, "poll_interval_s": 0.05}})
    (tmp_path / "data").mkdir()
    from service.storage.db import upgrade

    upgrade(settings.sqlalchemy_url)
    with running_app(settings) as (app, client, keys):
        body = client.get("/metrics", headers={"X-API-Key": keys["reader"]}).text
    exposed = set(re.findall(r"^# TYPE (hvcb_[a-z_]+) ", body, re.M))
    missing = sorted(used - exposed)
    assert not missing, f"the rules use metrics /metrics does not expose: {missing}"
