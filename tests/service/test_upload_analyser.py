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


def test_upload_co_record_without_operation_is_refused_in_words(env, generic):
    text, _ = export_text(Spec())
    r = env.client.post(URL.format(generic), headers=env.h("operator"), files=[("files", ("co.csv", text.encode()))])
    assert r.status_code == 422
    assert "holds C-O operations; say which to store with operation=open" in r.json()["detail"]


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
