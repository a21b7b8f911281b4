"""The spring setting of a stored close–open pair and the commissioning pair (issue 39): API,
``hvcb commission``, and the operation page's text."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest

from tests.conftest import BREAKER_FILE
from tests.pair_rows import store_pair

T0 = datetime(2026, 3, 1, 9, 0, tzinfo=timezone.utc)


@pytest.fixture
def unit(env, breaker):
    """A unit 1 % stiffer than the design (which no pair can see), with a pair at +1 step (its
    commissioning record), a pair at +3 steps a day later, and an opening too long after its closing to pair with it."""
    from service.storage import crud

    with env.Session() as s, s.begin():
        bid = crud.register_breaker_file(s, path=BREAKER_FILE, tag="SP1").id
    ref = store_pair(env.Session, breaker, breaker_id=bid, at=T0, steps=1.0, friction=1.02, kappa=1.01, key="ref")
    later = store_pair(env.Session, breaker, breaker_id=bid, at=T0 + timedelta(days=1), steps=3.0, friction=0.95,
                       kappa=1.01, key="later")
    # an opening 20 minutes after its closing: too long for one friction state, so no pair
    lone = store_pair(env.Session, breaker, breaker_id=bid, at=T0 + timedelta(days=5), steps=0.0, key="lone",
                      gap=timedelta(minutes=20))[1]
    return bid, ref, later, lone


def test_setting_from_the_design_seat_then_from_the_commissioning_pair(env, unit, breaker):
    from service.mechanics.spring_setting import steps_per_kO

    bid, ref, later, _ = unit
    r = env.client.get(f"/api/v1/operations/{later[1]}/setting", headers=env.h("reader"))
    assert r.status_code == 200, r.text
    s = r.json()
    assert s["status"] == "ok" and (s["closing_id"], s["opening_id"]) == later
    # the unit's +1 % spring rate reads as +0.42 steps more; the interval holds the ±3 % tolerance
    assert s["steps"] == pytest.approx(3.0 + 0.01 * (steps_per_kO(breaker) + 3.0), abs=1e-6)
    assert s["ci95"][0] < 3.0 < s["ci95"][1] and s["kO_sd_steps"] > 0.5 and s["reference"] is None
    assert s["friction"] == pytest.approx(0.95 * 1.0, abs=0.02)
    width_unread = s["ci95"][1] - s["ci95"][0]
    assert env.client.get(f"/api/v1/breakers/{bid}/commissioning", headers=env.h("reader")).status_code == 404
    # a reader may not commission; an operator records the pair at +1 step
    body = {"operation_id": ref[0], "known_steps": 1.0}
    assert env.client.post(f"/api/v1/breakers/{bid}/commissioning", json=body,
                           headers=env.h("reader")).status_code == 403
    c = env.client.post(f"/api/v1/breakers/{bid}/commissioning", json=body, headers=env.h("operator"))
    assert c.status_code == 201, c.text
    assert (c.json()["closing_id"], c.json()["opening_id"]) == ref and c.json()["known_steps"] == 1.0
    s = env.client.get(f"/api/v1/operations/{later[0]}/setting", headers=env.h("reader")).json()
    assert s["steps"] == pytest.approx(3.0 + 0.02, abs=1e-6)  # κ's offset gone; κ's 1 % of the 2-step change left
    assert s["nearest"] == 3 and s["kO_sd_steps"] == 0.0 and s["ci95"][1] - s["ci95"][0] < 0.5 * width_unread
    assert s["reference"]["id"] == c.json()["id"] and "commissioning pair" in s["basis"]
    got = env.client.get(f"/api/v1/breakers/SP1/commissioning", headers=env.h("reader")).json()
    assert got["id"] == c.json()["id"] and got["reading"]["steps"] == pytest.approx(1.0 + 0.01 * (steps_per_kO(breaker) + 1.0), abs=1e-6)


def test_no_pair_is_said_in_words(env, unit):
    bid, _, _, lone = unit
    s = env.client.get(f"/api/v1/operations/{lone}/setting", headers=env.h("reader")).json()
    assert s["status"] == "none" and "no closing of this breaker within 15 minutes" in s["reason"]
    r = env.client.post(f"/api/v1/breakers/{bid}/commissioning", json={"operation_id": lone, "known_steps": 0},
                        headers=env.h("operator"))
    assert r.status_code == 409 and "no closing of this breaker within 15 minutes" in r.json()["detail"]
    r = env.client.post(f"/api/v1/breakers/{bid}/commissioning", json={"operation_id": lone, "known_steps": 99},
                        headers=env.h("operator"))
    assert r.status_code == 422


def test_hvcb_commission_records_the_pair(env, unit, db_url, tmp_path, capsys):
    from service.cli import main

    bid, ref, later, lone = unit
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'data_dir = "{tmp_path / "data"}"\ndatabase_url = "{db_url}"\n')
    assert main(["commission", "SP1", "--operation", str(ref[1]), "--steps", "1", "--by", "commissioning engineer",
                 "--config", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert f"commissioning pair closing {ref[0]} / opening {ref[1]} at +1 nut steps" in out
    assert "offset +0.43 steps removed" in out  # 1 % of kO: 0.42 steps, and 1 % of the 1-step seat
    got = env.client.get(f"/api/v1/breakers/{bid}/commissioning", headers=env.h("reader")).json()
    assert got["recorded_by"] == "commissioning engineer" and got["opening_id"] == ref[1]
    assert main(["commission", "SP1", "--operation", str(lone), "--steps", "0", "--config", str(cfg)]) == 2
    assert "no closing of this breaker within 15 minutes" in capsys.readouterr().err
