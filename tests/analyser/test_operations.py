"""Close–open records: detect finds every operation from travel and coils; fit picks one."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from drivers.capture_file import read_capture
from service.acquisition.capture_file import breaker_reading
from service.acquisition.recording import detect_capture
from service.acquisition.trigger import TriggerSettings
from service.breaker_file import load_breaker
from service.estimation import fit_capture
from service.estimation.window import FitError

from tests.conftest import REPO, shared_dir

from .export_gen import Spec, write_export

GENERIC = str(REPO / "config/breakers/generic-analyser.toml")
EXAMPLE = shared_dir() / "realworld" / "analyser-csv" / "example-CO-10kHz.csv"


def _record(tmp_path, **kw):
    path = tmp_path / "rec.csv"
    truth = write_export(path, Spec(**kw))
    b = load_breaker(GENERIC)
    return read_capture(path, **breaker_reading(b), rate=kw.get("rate") if not kw.get("header", True)
                        else None), b, truth


@pytest.mark.parametrize("sequence,length", [("CO", 400), ("O-CO", 700), ("O", 150), ("C", 150)])
def test_detect_every_operation_with_coil_command(tmp_path, sequence, length):
    cap, b, truth = _record(tmp_path, sequence=sequence, length_ms=length)
    found = detect_capture(cap, TriggerSettings.from_breaker(b))
    assert [op.operation for op in found] == [e["operation"] for e in truth["events"]]
    for op, e in zip(found, truth["events"]):
        assert "command_from_coil" in op.flags
        assert op.window_start_s == pytest.approx(e["command_s"], abs=1e-3)  # the coil's rise
        d = op.to_dict()
        if op.operation == "open":
            assert d["motion_start_s"] == pytest.approx(e["onset_s"], abs=4e-3)
        else:  # the closing's output shaft moves once the cam's free run ends (~13 ms after release)
            assert e["onset_s"] < d["motion_start_s"] < e["onset_s"] + 0.025
        assert d["command"].startswith("coil C")


@pytest.mark.parametrize("rate", [5_000, 10_000])
def test_fit_opening_of_a_co_record_unknown_design(tmp_path, rate):
    cap, b, truth = _record(tmp_path, rate=rate)
    r = fit_capture(cap, b, "open")
    p = truth["params"]
    for name in ("AO", "BO", "DO", "EO"):
        lo, hi = r.ci95[name]
        assert lo < p[name] < hi or abs(r.parameters[name] - p[name]) < 3 * r.stderr[name], name
    a = r.structure["alpha0"]
    assert abs(a["value"] - truth["alpha0"]) < 3 * a["stderr"] + 1e-3
    ev = truth["events"][1]
    assert r.window_s[0] == pytest.approx(ev["command_s"], abs=1e-3)
    assert r.window_s[0] + r.onset_delay_s == pytest.approx(ev["onset_s"], abs=1e-3)  # coil-to-motion, 15 ms
    assert r.picked == {"operation": "open", "index": 0, "of": 1, "record_operations": ["close", "open"]}
    c = r.characteristics_record
    assert c["stroke_mm"] == 182.0 and c["max_travel_mm"] > 182.0 and 3.0 < c["average_speed_m_s"] < 10.0


def test_alpha0_uncertainty_widens_the_cis(tmp_path):
    """The same curve fitted with α0 known (the reference design) has narrower CIs."""
    cap, b, _ = _record(tmp_path)
    est = fit_capture(cap, b, "open")
    import dataclasses

    known = fit_capture(cap, dataclasses.replace(b, estimate_structure=()), "open")
    assert est.stderr["AO"] > known.stderr["AO"]
    assert est.stderr["EO"] > known.stderr["EO"]


def test_index_picks_among_several(tmp_path):
    cap, b, truth = _record(tmp_path, sequence="O-CO", length_ms=700)
    first = fit_capture(cap, b, "open", index=0)
    second = fit_capture(cap, b, "open", index=1)
    assert first.window_s[0] == pytest.approx(truth["events"][0]["command_s"], abs=1e-3)
    assert second.window_s[0] == pytest.approx(truth["events"][2]["command_s"], abs=1e-3)
    assert second.picked["of"] == 2
    with pytest.raises(FitError, match=r"--index 2 asks for opening 3, but the record holds 2"):
        fit_capture(cap, b, "open", index=2)


def test_closing_refused_without_cam_table(tmp_path):
    cap, b, _ = _record(tmp_path)
    with pytest.raises(FitError, match="no cam table: the closing model needs the camshaft-to-output-shaft cam"):
        fit_capture(cap, b, "close")


def test_closing_fitted_when_the_breaker_file_has_the_cam(tmp_path):
    """A known design (the reference's cam and α0) recorded in mm: its closing is fitted."""
    import shutil

    shutil.copy(REPO / "config/breakers/reference-252kV.cam.csv", tmp_path)
    src = (REPO / "config/breakers/reference-252kV.toml").read_text().replace(
        "stroke_rad = 1.0 ", 'stroke_rad = 1.0\nrecord_unit = "mm"\nrecord_zero = "open"\nmm_per_rad = 182.0\n#')
    (tmp_path / "ref-mm.toml").write_text(src)
    b = load_breaker(tmp_path / "ref-mm.toml")
    path = tmp_path / "rec.csv"
    truth = write_export(path, Spec())
    cap = read_capture(path, **breaker_reading(b))
    r = fit_capture(cap, b, "close")
    for name in ("AC", "BC", "CC"):
        assert abs(r.parameters[name] - truth["params"][name]) < 4 * r.stderr[name] + 0.01 * truth["params"][name], name


def test_no_such_operation_in_record(tmp_path):
    cap, b, _ = _record(tmp_path, sequence="C", length_ms=150)
    with pytest.raises(FitError, match=r"no opening found in this record \(closing at 0\.005 s\)"):
        fit_capture(cap, b, "open")


@pytest.mark.skipif(not EXAMPLE.is_file(), reason="shared analyser example not found")
def test_acceptance_shared_co_record_detect_and_fit():
    run = [sys.executable, "-m", "service.cli"]
    det = subprocess.run(run + ["detect", str(EXAMPLE), "--breaker", GENERIC, "--json"],
                         capture_output=True, text=True, timeout=120, cwd=REPO)
    assert det.returncode == 0, det.stderr
    ops = json.loads(det.stdout)
    assert [o["operation"] for o in ops] == ["close", "open"]
    assert ops[0]["t_start_s"] == pytest.approx(0.0, abs=2e-3)     # close coil at 0 ms
    assert ops[1]["t_start_s"] == pytest.approx(0.300, abs=2e-3)   # trip coil at t_co = 300 ms
    # motion_start_s is where the travel has left its rest by 2 % of the stroke: after the
    # README's onset (~314 ms) by the 2.8 ms the reference model needs to move that far.
    assert 0.314 <= ops[1]["motion_start_s"] <= 0.314 + 2.8e-3 + 2e-3
    fit = subprocess.run(run + ["fit", str(EXAMPLE), "--breaker", GENERIC, "--operation", "open", "--json"],
                         capture_output=True, text=True, timeout=300, cwd=REPO)
    assert fit.returncode == 0, fit.stderr
    out = json.loads(fit.stdout)
    assert out["operation"] == "open" and out["command_source"].startswith("coil C4")
    assert out["rmse_rad"] < 1.5 * out["noise_rad"]
    # The example is the reduced model of the reference breaker on a 182 mm stroke (its README):
    # per unit stroke, its design values must lie in the CIs (which carry α0's and CO's uncertainty).
    design = load_breaker(REPO / "config/breakers/reference-252kV.toml")
    truth = design.design_parameters()
    for name in ("AO", "BO", "DO", "EO"):
        lo, hi = out["ci95"][name]
        assert lo < truth[name] < hi, (name, out["parameters"][name], lo, hi)
    for name, true in (("alpha0", design.alpha0), ("CO", design.CO)):
        lo, hi = out["structure"][name]["ci95"]
        assert lo < true < hi, (name, out["structure"][name])
    assert out["characteristics_record"]["stroke_mm"] == 182.0
    close = subprocess.run(run + ["fit", str(EXAMPLE), "--breaker", GENERIC, "--operation", "close"],
                           capture_output=True, text=True, timeout=120, cwd=REPO)
    assert close.returncode != 0 and "no cam table" in close.stderr and "Traceback" not in close.stderr


@pytest.mark.parametrize("alpha0", [0.5, 0.85])
def test_alpha0_found_far_from_the_files_starting_guess(tmp_path, monkeypatch, alpha0):
    """The unknown design's α0 comes from the curve, not from the file's 0.70."""
    import dataclasses

    from . import export_gen

    base = export_gen.truth
    monkeypatch.setattr(export_gen, "truth", lambda: (dataclasses.replace(base()[0], alpha0=alpha0), base()[1]))
    cap, b, _ = _record(tmp_path)
    r = fit_capture(cap, b, "open")
    a = r.structure["alpha0"]
    assert abs(a["value"] - alpha0) < 3 * a["stderr"] + 2e-3, a
    assert r.rmse_rad < 1.3 * r.noise_rad


def test_co_estimated_from_the_curve(tmp_path, monkeypatch):
    """The unknown design's puffer damping CO comes from the curve, not the file's 92.6 s^-1."""
    import dataclasses

    from . import export_gen

    base = export_gen.truth
    b0 = base()[0]
    slow = dataclasses.replace(b0, caec=2.0 * b0.caec)  # CO 185 s^-1
    monkeypatch.setattr(export_gen, "truth", lambda: (slow, base()[1]))
    cap, b, _ = _record(tmp_path, length_ms=600)  # the slower opening needs a longer record
    r = fit_capture(cap, b, "open")
    lo, hi = r.structure["CO"]["ci95"]
    assert lo < slow.CO < hi and hi < 1.5 * slow.CO, r.structure["CO"]
    assert r.rmse_rad < 1.3 * r.noise_rad
