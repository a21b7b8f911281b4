"""The recorded channels of an analyser record: kept in hvcb's COMTRADE with their units and read
back, decimated together, the command and contact instants, and the analyser-vs-hvcb rows."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drivers.capture_file import load_capture_bytes, read_capture
from service.acquisition.capture_file import breaker_reading
from service.acquisition.recorded_channels import (
    channel_indices,
    operation_events,
    recorded_channels,
)
from service.breaker_file import load_breaker
from service.decimation import shared_minmax_indices
from service.estimation.analyser_compare import analyser_comparison
from service.estimation.record import upload_operations
from service.storage.spool import write_capture_file

from .export_gen import Spec, export_text

GENERIC = "config/breakers/generic-analyser.toml"


@pytest.fixture(scope="module")
def ops():
    b = load_breaker(GENERIC)
    cap = load_capture_bytes(export_text(Spec())[0].encode(), name="co.csv", **breaker_reading(b))
    return b, upload_operations(cap, b, None)


def test_every_operation_of_a_co_record_with_every_channel(ops):
    _, found = ops
    assert [k for _, k in found] == ["close", "open"]
    for cap, _ in found:
        assert {(a.name, a.unit) for a in cap.aux} == {("C1", "A"), ("C2", "A"), ("C3", "A"), ("C4", "A"), ("C5", "A"),
                                                       ("C6", "A"), ("T1", "mm"), ("R1", "µΩ"), ("I1", "A")}


def test_channels_survive_the_stored_comtrade(ops, tmp_path):
    _, found = ops
    cap = found[1][0]
    path, _ = write_capture_file(cap, tmp_path, "op")
    cfg = path.read_text(encoding="ascii")
    assert ",aux R1,,,uOhm," in cfg and ",aux C4,,,A," in cfg  # the .cfg stays ASCII
    back = read_capture(path)
    assert [(a.name, a.kind, a.unit) for a in back.aux] == [(a.name, a.kind, a.unit) for a in cap.aux]
    for a, o in zip(back.aux, cap.aux):  # within half an int16 step of the channel's range
        assert np.max(np.abs(a.data - o.data)) <= 0.5 * max(np.ptp(o.data), 1.0) / 65534 * 1.01
    assert back.meta["command_s"] == pytest.approx(cap.meta["command_s"])


def test_anyone_elses_comtrade_gets_no_aux_from_channel_names_alone(ops, tmp_path):
    """Only channels hvcb's own .hdr lists are read back: a field file's 'aux X' is not guessed."""
    _, found = ops
    path, _ = write_capture_file(found[1][0], tmp_path, "op")
    path.with_suffix(".hdr").write_text("free text from a recorder\n")
    assert read_capture(path).aux == ()


def test_one_minmax_decimation_keeps_every_channels_extremes(ops):
    _, found = ops
    cap = found[1][0]
    idx = channel_indices(cap, 300)
    assert idx.size <= 302 and np.all(np.diff(idx) > 0)
    for a in cap.aux:  # every channel's minimum and maximum survive
        assert a.data[idx].max() == a.data.max() and a.data[idx].min() == a.data.min()
    ch = recorded_channels(cap, idx)
    assert len(ch["C4"]["values"]) == idx.size and ch["R1"]["unit"] == "µΩ"
    assert shared_minmax_indices([np.arange(10.0)], 300).tolist() == list(range(10))


def test_contact_instant_from_the_dcrm_else_from_the_travel(ops):
    b, found = ops
    for cap, kind in found:
        ev = operation_events(cap, kind, b.stroke)
        assert ev["contact_event"] == ("contact part" if kind == "open" else "contact touch")
        assert ev["contact_source"].startswith("DCRM R1") and ev["contact_s"] > ev["command_s"]
        # without the DCRM, the travel's contact point (20 % / 80 % of the stroke) stands in
        bare = replace(cap, aux=tuple(a for a in cap.aux if a.kind != "resistance"))
        ev2 = operation_events(bare, kind, b.stroke)
        assert ev2["contact_source"] == f"travel at {20 if kind == 'open' else 80}% of the stroke"
        # the synthetic DCRM steps where the travel passes 20 % of the stroke from open/closed
        assert ev2["contact_s"] == pytest.approx(ev["contact_s"], abs=0.6e-3)


def test_analyser_rows_only_where_both_exist():
    analyser = {"results": {"open_velocity_m_s": {"T1": 5.9}, "open_datum_velocity_m_s": {"T1": 5.0},
                            "open_rebound_mm": {"T1": "∞"}, "close_over_travel_mm": {"T1": 3.0},
                            "open_time_ms": {"T1": 0.0}}}
    record = {"channel": "T1", "average_speed_m_s": 5.95, "rebound_mm": 1.2, "overtravel_mm": 2.0,
              "operating_time_s": 0.031}
    rows = analyser_comparison(analyser, record, "open")
    # the velocity line wins over the datum velocity; ∞ and the analyser's 0 are left out;
    # a closing's over-travel is no opening's
    assert [(r["quantity"], r["analyser"], r["hvcb"]) for r in rows] == [("speed", 5.9, 5.95)]
    assert rows[0]["difference"] == pytest.approx(0.05)
    close = analyser_comparison(analyser, record, "close")
    assert [(r["quantity"], r["difference"]) for r in close] == [("overtravel", -1.0)]
    for name in ("open_time_ms", "opening_time_ms"):
        timed = analyser_comparison({"results": {name: {"T1": 30.0}}}, record, "open")
        assert timed[0]["quantity"] == "opening time" and timed[0]["difference"] == pytest.approx(1.0)
    assert analyser_comparison(None, record, "open") == [] and analyser_comparison(analyser, None, "open") == []
