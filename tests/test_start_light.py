"""A command starts at once (issue 44 items 4 and 7): its help and the settings load nothing heavy,
the settings import nothing from the notifications, and the [alarms] and [notifications] sections
are still refused in words, when first used (the service: at start). The time itself is measured
by bench/cli_start.py, not here."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("scipy", "cma", "numba", "matplotlib", "service.reports.pdf", "service.alarms.design")


def loaded_after(code: str) -> set[str]:
    probe = f"import sys\n{code}\nimport json; print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=True)
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize("command", ["fit", "diagnose", "report", "serve", "study", "refit"])
def test_a_commands_help_loads_no_heavy_module(command):
    code = ("import contextlib, io\nfrom service.cli import main\n"
            f"with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    try: main([{command!r}, '--help'])\n    except SystemExit: pass")
    mods = loaded_after(code)
    assert "service.cli" in mods
    heavy = sorted(m for m in mods if m.split(".")[0] in HEAVY or m in HEAVY)
    assert not heavy, f"hvcb {command} --help loaded {heavy}"


def test_loading_the_settings_designs_no_threshold():
    mods = loaded_after("from service.settings import load_settings\nload_settings()")
    assert "service.settings" in mods
    assert "service.alarms.design" not in mods and "scipy" not in mods


def test_the_settings_import_nothing_from_the_notifications():
    tree = ast.parse((ROOT / "service" / "settings.py").read_text(encoding="utf-8"))
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert names and not [n for n in names if n.startswith("service.notifications")]


def test_bad_alarm_settings_are_refused_in_words_when_first_used(tmp_path):
    from service.settings import load_settings

    s = load_settings(data_dir=tmp_path, alarms={"h_alarn": 5.0})  # loads: nothing designed yet
    with pytest.raises(ValueError, match="unknown alarm setting h_alarn"):
        s.drift_settings


def test_the_thresholds_are_designed_once_per_section(tmp_path):
    from service.settings import load_settings

    a = load_settings(data_dir=tmp_path, alarms={"baseline_n": 7})
    b = load_settings(data_dir=tmp_path, alarms={"baseline_n": 7})
    c = load_settings(data_dir=tmp_path, alarms={"baseline_n": 8})
    assert a.drift_settings is b.drift_settings
    assert c.drift_settings is not a.drift_settings and c.drift_settings.baseline_n == 8
    assert a.drift_settings.h_warning < a.drift_settings.h_alarm


def test_a_bad_notification_route_is_refused_at_start_in_words(tmp_path):
    from service.api.app import create_app
    from service.settings import load_settings

    s = load_settings(data_dir=tmp_path, notifications={"routes": [{"name": "x", "kind": "webhook",
                                                                     "url": "ftp://nowhere"}]})
    with pytest.raises(ValueError, match=r"notification route 'x': a webhook needs url"):
        create_app(s, start_monitor=False)
