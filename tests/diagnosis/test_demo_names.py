"""The demo's diagnosis never names an effect the demo does not inject (issue 42): its scripted
history (service/api/demo.py) diagnosed as the breaker page does, a group of openings before the
oil leak and one during it. No browser: the same captures the demo's DAQ plays."""

from itertools import islice

import pytest

from service.api.demo import MILD_EFFECTS, DemoScript, history
from service.diagnosis import diagnose


@pytest.fixture(scope="module")
def openings(breaker):
    caps = [(i, c) for i, kind, c in islice(history(breaker, DemoScript()), 48) if kind == "open"]
    return caps


@pytest.mark.parametrize("span", [(0, 5), (26, 31)])
def test_the_demo_names_only_what_it_injects(breaker, openings, span):
    caps = [c for i, c in openings if span[0] <= i < span[1]]
    assert len(caps) == span[1] - span[0]
    r = diagnose(caps, breaker, "open", next_measurements=False)
    injected = set(MILD_EFFECTS["open"])
    named = set(r["effects"]) if r["status"] == "named" else set()
    assert named <= injected, f"the demo named {named - injected}, which it does not inject"
    assert r["status"] in {"none", "named", "ambiguous", "unexplained"}
