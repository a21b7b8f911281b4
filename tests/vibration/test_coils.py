"""The coil currents of analyser records: peak, armature dip and current end per energisation, in
``hvcb inspect --json`` as ``coils`` and in the fit's characteristics, beside the analyser's own
peak where the header states one (within 3 %)."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from service.vibration import coil_results
from tests.analyser.export_gen import Spec, export_text
from tests.conftest import shared_dir

FS = 10_000.0


def trip_coil(t_on=0.010, dip_at=0.024, dip_a=0.6, end=0.070, noise=0.005, seed=0):
    """A trip coil's current [A]: an L/R rise to 2 A, the armature's dip, the auxiliary contact's break."""
    t = np.arange(0.0, 0.12, 1 / FS)
    rise = np.where(t >= t_on, 2.0 * (1 - np.exp(-(t - t_on) / 4e-3)), 0.0)
    dip = np.where(np.abs(t - dip_at) < 6e-3, -dip_a * np.cos(np.pi * (t - dip_at) / 12e-3), 0.0) if dip_a else 0.0
    cur = np.where(t < end, rise + dip, 0.0)
    return cur + np.abs(np.random.default_rng(seed).normal(0, noise, t.size))


def test_peak_dip_and_end_of_a_trip_coil():
    (r,) = coil_results("C4", trip_coil(), FS)
    assert r["energised_s"] == pytest.approx(0.010, abs=0.3e-3)
    assert r["armature_dip_s"] == pytest.approx(0.014, abs=0.7e-3)
    assert r["current_end_s"] == pytest.approx(0.060, abs=0.7e-3)
    assert r["peak_current_a"] == pytest.approx(2.0, rel=0.03)


def test_no_dip_and_a_current_that_runs_off_the_record_are_none_with_reasons():
    (r,) = coil_results("C1", trip_coil(dip_a=0.0, end=1.0), FS)
    assert r["armature_dip_s"] is None and "no armature dip" in r["armature_dip_reason"]
    assert r["current_end_s"] is None and "end of the record" in r["current_end_reason"]


def test_an_idle_coil_is_not_listed_and_two_energisations_are_two_pulses():
    assert coil_results("C2", np.abs(np.random.default_rng(1).normal(0, 0.005, 1200)), FS) == []
    twice = trip_coil(end=0.04) + np.roll(trip_coil(end=0.04, seed=3), 600)
    pulses = coil_results("C4", twice, FS)
    assert [p["pulse"] for p in pulses] == [0, 1]
    assert pulses[1]["energised_s"] - pulses[0]["energised_s"] == pytest.approx(0.06, abs=0.5e-3)


def test_bare_export_without_rate_gives_the_peak_and_no_times():
    (r,) = coil_results("C4", trip_coil(), None)
    assert r["peak_current_a"] > 1.9 and r["current_end_s"] is None and "sample rate" in r["current_end_reason"]


def _inspect(path, *extra):
    proc = subprocess.run([sys.executable, "-m", "service.cli", "inspect", str(path), "--json", *extra],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_inspect_json_lists_the_coils_of_the_layout_example():
    example = shared_dir() / "realworld" / "analyser-csv" / "example-CO-10kHz.csv"
    if not example.exists():
        pytest.skip(f"{example} is absent")
    coils = {c["channel"]: c for c in _inspect(example)["coils"]}
    assert sorted(coils) == ["C1", "C2", "C3", "C4", "C5", "C6"]
    for name, c in coils.items():
        assert abs(c["peak_difference_rel"]) <= 0.03, (name, c)
        assert c["current_end_s"] is not None or c["current_end_reason"]
        assert c["armature_dip_s"] is not None or c["armature_dip_reason"]
    assert coils["C4"]["energised_s"] == pytest.approx(0.30, abs=1e-3)


@pytest.mark.parametrize("spec", [Spec(), Spec(sequence="O-CO", gap_ms=200.0, length_ms=800.0, seed=4), Spec(rate=20_000.0, seed=5)])
def test_inspect_json_coils_of_generated_exports(tmp_path, spec):
    text, truth = export_text(spec)
    path = tmp_path / "rec.csv"
    path.write_text(text)
    coils = _inspect(path)["coils"]
    stated = {c["channel"]: c for c in coils if "analyser_peak_a" in c}
    assert set(stated) == {"C1", "C4"}  # the header states C1 and C4
    assert all(abs(c["peak_difference_rel"]) <= 0.03 for c in stated.values())
    trips = [c for c in coils if c["channel"] == "C4"]
    commands = [e["command_s"] for e in truth["events"] if e["operation"] == "open"
                and e["command_s"] < spec.length_ms * 1e-3 - 0.01]  # the commands inside the record
    assert [round(c["energised_s"], 3) for c in trips] == pytest.approx(commands, abs=1e-3)


# -- issue 56 item 2: the peak as the analyser reads it; issue 57: a header peak that is no current

def _example():
    example = shared_dir() / "realworld" / "analyser-csv" / "example-CO-10kHz.csv"
    if not example.exists():
        pytest.skip(f"{example} is absent")
    return example


def test_every_coil_peak_of_the_layout_example_is_the_analysers_reading():
    from drivers.analyser.parser import parse_analyser

    example = _example()
    rec = parse_analyser(example.read_text(encoding="utf-8"), source=str(example))
    raw = {c.name: np.asarray(c.data, float) for c in rec.channels if c.kind == "coil_current"}
    coils = _inspect(example)["coils"]
    assert sorted(c["channel"] for c in coils) == ["C1", "C2", "C3", "C4", "C5", "C6"]  # one pulse each
    for c in coils:
        start = int(round(c["energised_s"] * FS))
        end = start + int(round((c["current_end_s"] or 0.05) * FS))
        # the largest raw sample of the pulse: what the analyser's own coil peak is
        assert c["peak_current_a"] == pytest.approx(raw[c["channel"]][start:end].max(), abs=1e-3), c
        assert abs(c["peak_difference_rel"]) <= 0.03, c  # the header's own number
        assert c["peak_current_smoothed_a"] < c["peak_current_a"]  # the 1 ms average, beside it


def test_a_one_sample_spike_is_the_raw_peak_and_not_the_smoothed_one():
    cur = trip_coil()
    i = int(0.040 * FS)  # on the plateau
    cur[i] = 3.1
    (r,) = coil_results("C4", cur, FS, analyser_peak_a=3.1)
    assert r["peak_current_a"] == pytest.approx(3.1)  # as the analyser reads it: the sample itself
    # the 1 ms average (10 samples) carries a tenth of the spike's 1.1 A excess, no more
    assert r["peak_current_smoothed_a"] == pytest.approx(2.0 + 1.1 / 10, rel=0.03)
    assert r["peak_difference_rel"] == pytest.approx(0.0, abs=1e-3)
    rest = trip_coil()
    rest[int(0.004 * FS)] = 3.1  # a spike before the energisation is no pulse and no peak
    (r,) = coil_results("C4", rest, FS)
    assert r["peak_current_a"] == pytest.approx(2.0, rel=0.03) and r["energised_s"] == pytest.approx(0.010, abs=0.3e-3)


def test_the_header_peak_is_compared_with_the_coils_largest_pulse_only():
    first = trip_coil(end=0.04)
    second = np.roll(trip_coil(end=0.04, seed=3), 600) * 1.2  # a CO record's second, larger energisation
    pulses = coil_results("C4", first + second, FS, analyser_peak_a=float((first + second).max()))
    assert [p["pulse"] for p in pulses] == [0, 1]
    assert "analyser_peak_a" not in pulses[0]
    assert pulses[1]["peak_difference_rel"] == pytest.approx(0.0, abs=1e-3)


@pytest.mark.parametrize("word", ["inf", "∞", "NaN", "-inf", "1e999", "lots"])
def test_a_header_peak_that_is_no_current_is_refused_in_words(tmp_path, word):
    (r,) = coil_results("C4", trip_coil(), FS, analyser_peak_a=word if word != "1e999" else float(word))
    assert "peak_difference_rel" not in r and "analyser_peak_a" not in r
    assert "C4" in r["analyser_peak_reason"] and "not" in r["analyser_peak_reason"]
    text, _ = export_text(Spec())
    path = tmp_path / "rec.csv"
    stated = re.sub(r"Coil Current \(A\)\(C4\) :,[0-9.]+", f"Coil Current (A)(C4) :,{word}", text)
    assert stated != text
    path.write_text(stated)
    proc = subprocess.run([sys.executable, "-m", "service.cli", "inspect", str(path), "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr

    def refuse(w):
        raise AssertionError(f"not strict JSON: {w}")
    c4 = [c for c in json.loads(proc.stdout, parse_constant=refuse)["coils"] if c["channel"] == "C4"]
    assert c4 and "peak_difference_rel" not in c4[0] and "C4" in c4[0]["analyser_peak_reason"]


def test_na_in_the_header_states_nothing():
    (r,) = coil_results("C4", trip_coil(), FS, analyser_peak_a="NA")
    assert "analyser_peak_reason" not in r and "analyser_peak_a" not in r
