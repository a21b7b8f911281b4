"""An analyser export uploaded through the API and the web page: the same reader as the CLI,
the chosen operation of a CO record stored, and the analyser's results on the operation page."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.analyser.export_gen import Spec, export_text

REPO = Path(__file__).resolve().parents[2]

URL = "/api/v1/breakers/{}/captures"


@pytest.fixture
def generic(env):
    from service.storage import crud

    with env.Session() as s, s.begin():
        row = crud.register_breaker_file(s, path=REPO / "config/breakers/generic-analyser.toml", tag="Q9")
        return row.id


def test_upload_co_record_stores_the_opening_and_page_shows_results(env, generic):
    text, _ = export_text(Spec())
    files = [("files", ("test-co.csv", text.encode()))]
    r = env.client.post(URL.format(generic), headers=env.h("operator"), files=files, data={"operation": "open"})
    assert r.status_code == 202, r.text
    assert r.json()["operation"] == "open"
    env.wait_fits(1)
    op_id = r.json()["operation_id"]
    op = env.client.get(f"/api/v1/operations/{op_id}", headers=env.h("reader")).json()
    assert op["fit"]["status"] == "done", op["fit"]
    from tests.web_forms import sign_in

    sign_in(env.client, env.keys["reader"])
    page = env.client.get(f"/operations/{op_id}")
    assert page.status_code == 200
    html = page.text
    assert 'id="analyser-results"' in html and "contact travel" in html and "182" in html
    assert "open rebound" in html and "1.5" in html and "TEST" in html  # the export's own figures
    assert 'id="record-unit"' in html and "m/s" in html            # characteristics in mm and m/s
    assert "alpha0" in html and "from the curve" in html           # the unknown design's α0
    result = op["fit"].get("result") or {}
    if result:  # the API shows the stored fit's own JSON: the stroke comes back in mm
        assert result["characteristics_record"]["stroke_mm"] == pytest.approx(182.0)


def _upload_co(env, breaker_id, text: str, name: str = "co.csv", **data):
    r = env.client.post(URL.format(breaker_id), headers=env.h("operator"),
                        files=[("files", (name, text.encode("utf-8")))], data=data)
    assert r.status_code == 202, r.text
    return r.json()


def test_one_upload_of_a_co_record_stores_its_closing_and_its_opening(env, generic):
    """The analyser's normal file: one request stores both operations, each with its own fit,
    flags and the record's results; the opening is fitted; every recorded channel is kept."""
    body = _upload_co(env, generic, export_text(Spec())[0])
    ops = body["operations"]
    assert [o["operation"] for o in ops] == ["close", "open"]
    assert body["operation_id"] == ops[0]["operation_id"] and len({o["capture_key"] for o in ops}) == 2
    env.wait_fits(2)
    close, opening = (env.client.get(f"/api/v1/operations/{o['operation_id']}", headers=env.h("reader")).json()
                      for o in ops)
    assert close["kind"] == "close" and opening["kind"] == "open"
    assert opening["fit"]["status"] == "done", opening["fit"]
    # the generic breaker has no cam table: the closing's own fit refuses in words, it is not skipped
    assert close["fit"]["status"] == "failed" and "cam" in close["fit"]["failure_reason"]
    curve = env.client.get(f"/api/v1/operations/{ops[1]['operation_id']}/curve?points=600",
                           headers=env.h("reader")).json()
    ch = curve["channels"]
    assert {n: c["unit"] for n, c in ch.items()} == {"C1": "A", "C2": "A", "C3": "A", "C4": "A", "C5": "A", "C6": "A",
                                                     "T1": "mm", "R1": "µΩ", "I1": "A"}
    assert all(len(c["values"]) == len(curve["t_s"]) for c in ch.values()) and len(curve["t_s"]) <= 602
    assert max(ch["C4"]["values"]) == pytest.approx(1.4, abs=0.03)      # the trip coil's peak survives
    assert min(ch["R1"]["values"]) == pytest.approx(48.0, abs=0.1) and max(ch["R1"]["values"]) == pytest.approx(8000.0)
    ev = curve["events"]
    assert ev["contact_event"] == "contact part" and ev["contact_source"].startswith("DCRM R1")
    # the export's truth: trip command, then the contacts part while the travel leaves 80 % closed
    assert ev["command_s"] is not None and 0.010 < ev["contact_s"] - ev["command_s"] < 0.030
    # a retry with the content hash finds both operations
    from service.jobs.upload import content_hash

    text = export_text(Spec(seed=7))[0]
    key = content_hash(text.encode(), b"")
    first = env.client.post(URL.format(generic), headers={**env.h("operator"), "Idempotency-Key": key},
                            files=[("files", ("co7.csv", text.encode()))])
    again = env.client.post(URL.format(generic), headers={**env.h("operator"), "Idempotency-Key": key},
                            files=[("files", ("co7.csv", text.encode()))])
    assert again.status_code == 200 and again.json()["status"] == "duplicate"
    assert [o["operation_id"] for o in again.json()["operations"]] == [o["operation_id"] for o in first.json()["operations"]]
    env.wait_fits(4)


def test_quirky_and_shared_records_upload_through_the_same_path(env, generic):
    """A header with ∞, units inside numbers and an unreadable date uploads; the quirks travel
    with the stored operation. The shared example (../shared/realworld/analyser-csv/) uploads too."""
    text = export_text(Spec())[0].replace("Open -Rebound(T1)(mm) :,1.50", "Open -Rebound(T1)(mm) :,∞").replace(
        "Voltage (kV) :,245", "Voltage (kV) :,765kV").replace("Test Date :,01-01-2026", "Test Date :,soon")
    body = _upload_co(env, generic, text, name="quirks.csv", operation="open")
    assert [o["operation"] for o in body["operations"]] == ["open"]
    example = REPO.parent / "shared" / "realworld" / "analyser-csv" / "example-CO-10kHz.csv"
    if not example.is_file():
        example = REPO / ".." / "shared" / "realworld" / "analyser-csv" / "example-CO-10kHz.csv"
    if example.is_file():
        shared = _upload_co(env, generic, example.read_text(encoding="utf-8"), name=example.name)
        assert [o["operation"] for o in shared["operations"]] == ["close", "open"]
    env.wait_fits(1)
    from service.acquisition.comtrade_writer import stored_analyser_results
    from service.storage import crud

    with env.Session() as s:
        path = crud.get_operation(s, operation_id=body["operation_id"]).capture_path
    kept = stored_analyser_results(path)
    assert kept["results"]["open_rebound_mm"]["T1"] == "∞" and kept["metadata"]["rated_voltage_kv"] == 765.0
    assert {u["name"] for u in kept["unparsed"]} == {"open_rebound_mm", "test_date"}
    op = env.client.get(f"/api/v1/operations/{body['operation_id']}", headers=env.h("reader")).json()
    assert "analyser header: 2 field(s) kept as text" in op["flags"]


def test_upload_bare_export_refused_in_words(env, generic):
    text, _ = export_text(Spec(header=False))
    r = env.client.post(URL.format(generic), headers=env.h("operator"), files=[("files", ("bare.csv", text.encode()))],
                        data={"operation": "open"})
    assert r.status_code == 422
    assert "bare.csv: a bare analyser export" in r.json()["detail"]


def test_agent_replay_of_analyser_exports_hands_on_each_operation(tmp_path):
    """An edge agent replaying analyser exports: every operation of each record is written as
    COMTRADE (travel in rad) and handed on to the outbox like a triggered capture."""
    from fleet_helpers import poll
    from service.acquisition.capture_file import read_capture
    from service.acquisition.daq_runner import DaqGroup, DaqRunner
    from service.breaker_file import load_breaker
    from service.settings import AcquisitionSettings

    from tests.analyser.export_gen import write_export

    b = load_breaker(REPO / "config/breakers/generic-analyser.toml")
    write_export(tmp_path / "co.csv", Spec())
    write_export(tmp_path / "oco.csv", Spec(sequence="O-CO", length_ms=700))
    acq = AcquisitionSettings(driver="replay", breaker=b.name, name="analyser",
                              replay={"files": [str(tmp_path / "co.csv"), str(tmp_path / "oco.csv")], "speed": None})
    got = []
    group = DaqGroup([DaqRunner(acq, b, tmp_path / "out", on_capture=lambda p, d: got.append((p, d.operation)))])
    group.start()
    try:
        poll(lambda: group.states()[0].state == "finished", 60, "the analyser replay to finish")
    finally:
        group.stop()
    assert [op for _, op in got] == ["close", "open", "open", "close", "open"]
    cap = read_capture(got[1][0])
    assert cap.travel.min() < 0.05 and cap.travel.max() > 0.95   # an opening, in rad from closed
