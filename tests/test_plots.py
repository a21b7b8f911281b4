"""matplotlib is an extra: without it, a figure request is a sentence with the install command."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from service.errors import UserError
from service.plots import INSTALL_HINT, pyplot, require_matplotlib

ROOT = Path(__file__).resolve().parents[1]

# Runs the CLI in a child where importing matplotlib fails, as in a core install.
HIDE_MATPLOTLIB = """
import importlib.abc, sys
class Hide(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None
sys.meta_path.insert(0, Hide())
import importlib.util
_find = importlib.util.find_spec
importlib.util.find_spec = lambda name, *a: None if name.split(".")[0] == "matplotlib" else _find(name, *a)
from service.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_without_matplotlib_the_error_names_the_extra(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "matplotlib" else real(name, *a))
    with pytest.raises(UserError, match=r"--plot need matplotlib, which is not installed: pip install 'hvcb\[plots\]'"):
        require_matplotlib("--plot")
    with pytest.raises(UserError, match=r"hvcb\[plots\]"):
        pyplot()


def test_diagnose_plot_without_matplotlib_stops_before_the_work(tmp_path):
    out = tmp_path / "r.png"
    proc = subprocess.run([sys.executable, "-c", HIDE_MATPLOTLIB, "diagnose", str(tmp_path / "absent.cfg"),
                           "--breaker", str(ROOT / "config/breakers/reference-252kV.toml"),
                           "--operation", "open", "--plot", str(out)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 2, proc.stderr
    # the missing extra is reported first, not the missing capture file (the check runs before the work)
    assert INSTALL_HINT in proc.stderr and "absent.cfg" not in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not out.exists()


def test_with_matplotlib_pyplot_uses_agg():
    pytest.importorskip("matplotlib")
    plt = pyplot()
    assert plt.get_backend().lower() == "agg"
