"""GET /operations/{id}/diagnosis: computed on demand as a job, then served from the database."""

import time

import numpy as np
import pytest

from comtrade_bytes import comtrade_pair
from drivers.synthetic import synthesize_capture
from service.prototypes.a import Effects, make_prototype_simulator


def _served(env, breaker):
    """A closing with a contact wipe posted, its diagnosis queued, polled until served: (the
    served body, the operation id)."""
    sim = make_prototype_simulator(breaker, Effects(contact_wipe=0.45), "close", method="fast")
    cap, _ = synthesize_capture(breaker, "close", breaker.design_parameters(), rng=np.random.default_rng(31),
                                simulate=sim)
    cfg, dat = comtrade_pair(cap)
    r = env.client.post("/api/v1/breakers/1/captures", headers=env.h("operator"),
                        files=[("files", ("c.cfg", cfg)), ("files", ("c.dat", dat))], data={"operation": "close"})
    assert r.status_code == 202, r.text
    op = r.json()["operation_id"]
    url = f"/api/v1/operations/{op}/diagnosis"
    assert env.client.get(url).status_code == 401
    first = env.client.get(url, headers=env.h("reader"))
    assert first.status_code == 202 and first.json()["status"] in ("queued", "running")
    deadline = time.monotonic() + 240
    while True:
        body = env.client.get(url, headers=env.h("reader"))
        if body.status_code == 200:
            break
        assert body.status_code == 202 and time.monotonic() < deadline, body.text
        time.sleep(0.5)
    return body.json(), op


def test_diagnosis_is_queued_then_served(env, breaker):
    out, op = _served(env, breaker)
    assert out["status"] == "done", out
    result = out["result"]
    assert {"gap", "candidates", "verdict"} <= set(result)
    assert any("contact_wipe" in k.split("+") for k in result["set"])      # the wipe is in the 90 % set
    assert env.client.get(f"/api/v1/operations/{op + 1000}/diagnosis", headers=env.h("reader")).status_code == 404


@pytest.mark.xfail(strict=True, reason="issue 54: the shipped scorer does not name the wipe of this one closing "
                   "(verdict 'ambiguous'); the none test refuses none here but names nothing")
def test_the_served_diagnosis_names_the_wipe(env, breaker):
    out, _ = _served(env, breaker)
    assert out["result"]["verdict"] == "contact_wipe"
