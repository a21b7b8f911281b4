"""A record with over-range travel samples on one pole, uploaded (issue 39 item 4): stored, both
operations kept, the opening fitted on a valid pole, and the masked spans listed on the
operation's API and page."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.analyser.export_gen import Spec, export_text

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def generic(env):
    from service.storage import crud

    with env.Session() as s, s.begin():
        return crud.register_breaker_file(s, path=REPO / "config/breakers/generic-analyser.toml", tag="OR1").id


def test_an_over_range_record_is_stored_fitted_on_the_valid_pole_and_its_spans_listed(env, generic):
    text, _ = export_text(Spec(wired_travel=(1, 2, 3), over_range={1: (325.0, 327.9, "∞")}))
    r = env.client.post(f"/api/v1/breakers/{generic}/captures", headers=env.h("operator"),
                        files=[("files", ("field.csv", text.encode("utf-8")))])
    assert r.status_code == 202, r.text
    ops = r.json()["operations"]
    assert [o["operation"] for o in ops] == ["close", "open"]
    env.wait_fits(2)
    close, opening = (env.client.get(f"/api/v1/operations/{o['operation_id']}", headers=env.h("reader")).json()
                      for o in ops)
    assert close["masked_samples"] == []
    (span,) = opening["masked_samples"]
    assert span["channel"] == "T1" and span["count"] == 30 and span["last_s"] - span["first_s"] == pytest.approx(2.9e-3)
    assert "over-range samples: T1 30" in opening["flags"]
    assert opening["fit"]["status"] == "done", opening["fit"]
    curve = env.client.get(f"/api/v1/operations/{ops[1]['operation_id']}/curve?points=600", headers=env.h("reader"))
    assert curve.status_code == 200 and "T1" in curve.json()["channels"]
    from tests.web_forms import sign_in

    sign_in(env.client, env.keys["reader"])
    html = env.client.get(f"/operations/{ops[1]['operation_id']}").text
    assert 'id="masked-samples"' in html and "Over-range samples" in html
    assert f"{1e3 * span['first_s']:.2f} ms" in html and ">30<" in html and "The fit used travel T2" in html
