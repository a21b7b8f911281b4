"""D5: a capture is stored byte for byte and read with the breaker file's channel names:
a breaker whose channels are TRV/VIB fits its uploads, draws its curves and shows its page."""

from __future__ import annotations

import re
import time
from pathlib import Path

from service.storage import crud

from .conftest import BREAKER_FILE, comtrade_pair, synth


def test_breaker_with_custom_channel_names_fits_its_uploads_end_to_end(env, breaker):
    text = BREAKER_FILE.read_text().replace('name = "reference-252kV"', 'name = "bay-trv"')
    text = re.sub(r'travel = "travel"', 'travel = "TRV"', text)
    text = re.sub(r'vibration = "vibration"', 'vibration = "VIB"', text)
    cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
    r = env.client.post("/api/v1/breakers", json={"breaker_file": text, "cam_table": cam, "tag": "Q7"}, headers=env.h())
    assert r.status_code == 201, r.text
    bid = r.json()["id"]

    cfg, dat = comtrade_pair(synth(breaker, "open", seed=5), travel="TRV", vibration="VIB")
    assert b",TRV," in cfg and b",travel," not in cfg
    r = env.client.post(f"/api/v1/breakers/{bid}/captures", headers=env.h("operator"),
                        files=[("files", ("rec.cfg", cfg)), ("files", ("rec.dat", dat))])
    assert r.status_code == 202, r.text
    op_id = r.json()["operation_id"]
    with env.Session() as s:
        path = Path(crud.get_operation(s, operation_id=op_id).capture_path)
    assert path.read_bytes() == cfg and path.with_suffix(".dat").read_bytes() == dat  # stored as sent

    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        op = env.client.get(f"/api/v1/operations/{op_id}", headers=env.h("reader")).json()
        if op["fit"]["status"] in ("done", "failed"):
            break
        time.sleep(0.2)
    assert op["fit"]["status"] == "done", op["fit"]
    assert op["fit"]["parameters"]["DO"] > 0

    curve = env.client.get(f"/api/v1/operations/{op_id}/curve", headers=env.h("reader"))
    assert curve.status_code == 200 and len(curve.json()["measured_rad"]) > 100
    assert any(v is not None for v in curve.json()["fitted_rad"])

    from .test_d15_session_rotation import sign_in

    sign_in(env.client, env.keys["reader"])
    assert env.client.get(f"/operations/{op_id}").status_code == 200
    js = env.client.get(f"/ui/operations/{op_id}/curves.json")
    assert js.status_code == 200 and js.json()["fit_status"] == "done"
