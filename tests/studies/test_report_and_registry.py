"""The output writers and the study registry behind ``hvcb study``."""

import json

import numpy as np
import pytest

from service.cli import main
from service.studies import commands, report
from service.studies.synthetic_sets import error_metrics, noise_sd_for_snr


def test_write_json_makes_strict_json(tmp_path):
    path = report.write_json(tmp_path / "sub", "x", {"a": np.float64(1.5), "b": np.nan,
                                                     "c": np.arange(3), "d": (np.int64(2), True)})
    data = json.loads(path.read_text())
    assert data == {"a": 1.5, "b": None, "c": [0, 1, 2], "d": [2, True]}


def test_write_markdown_has_title_table_and_sections(tmp_path):
    path = report.write_markdown(tmp_path, "t", "Title", [["r", 1.23456, float("nan")]],
                                 ["name", "v", "w"], sections=[("More", ["k"], [[3]])], notes=["n."])
    text = path.read_text()
    assert text.startswith("# Title")
    assert "| r | 1.235 | — |" in text
    assert "## More" in text and text.rstrip().endswith("n.")


def test_save_figure_writes_png(tmp_path):
    fig, ax = report.new_figure()
    ax.plot([0, 1], [1, 0])
    path = report.save_figure(fig, tmp_path / "f.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_registry_names_every_study_with_module_and_function():
    for name in ("identifiability", "sensitivity", "correlation", "optimizers", "conditions",
                 "classify", "gap"):
        module, func = commands.STUDIES[name].split(":")
        assert module.startswith("service.") and func


def test_unavailable_study_is_one_line_error(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(commands.STUDIES, "nothing", "service.studies.not_there:run")
    with pytest.raises(commands.StudyUnavailable, match="not available"):
        commands.load_study("nothing")
    with pytest.raises(commands.StudyUnavailable, match="unknown study"):
        commands.load_study("nope")


def test_cli_rejects_zero_workers(tmp_path, capsys):
    assert main(["study", "sensitivity", "--out", str(tmp_path), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "workers" in err


def test_snr_definition():
    theta = np.linspace(0, 1, 1001)
    sigma = noise_sd_for_snr(theta, 50.0)
    assert 10 * np.log10(np.mean(theta**2) / sigma**2) == pytest.approx(50.0)


def test_error_metrics_on_known_errors():
    m = error_metrics([100.0, 200.0], [101.0, 198.0])
    assert m["MAE"] == pytest.approx(1.5)
    assert m["RMSE"] == pytest.approx(np.sqrt(2.5))
    assert m["MRE_pct"] == pytest.approx(100 * (0.01 + 0.01) / 2)
    assert m["R2"] == pytest.approx(1 - 5 / 5000)
