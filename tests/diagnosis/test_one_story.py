"""The card tells one story (issue 29): the API's answer, the CLI's JSON and text, and the page
state one answer with one probability, the same number as the table's row for it."""

import json
import re

import numpy as np
import pytest

from service.api.routes_diagnoses import DiagnosisResult
from service.diagnosis import diagnose
from service.diagnosis.commands import _jsonable
from service.diagnosis.report import format_report
from service.mechanics.effects import in_words
from service.prototypes.a import groups as ga
from service.web.diagnosis_view import view
from service.web.render import build_templates


@pytest.fixture(scope="module")
def result(breaker):
    rng = np.random.default_rng(131)
    unit = ga.make_unit(rng, effects={})
    caps = [ga.simulate_capture(unit, "open", conditions=ga.draw_conditions(rng), rng=rng)[0] for _ in range(3)]
    return diagnose(caps, breaker, "open", next_measurements=False)


def test_api_cli_and_page_agree_on_every_number(result):
    r = json.loads(json.dumps(result, default=_jsonable))              # `hvcb diagnose --json`
    p = r["answer_probability"]
    assert p == r["probabilities"][r["answer"]]
    assert sum(r["probabilities"].values()) == pytest.approx(1.0)
    api = DiagnosisResult.model_validate(r).model_dump()                # GET /api/v1/.../diagnoses/{id}
    assert api["answer"] == r["answer"] and api["answer_probability"] == p == api["probabilities"][api["answer"]]
    text = format_report(result)                                        # `hvcb diagnose` (text)
    assert f"answer: {in_words(r['answer'])} ({r['answer']}), probability {p:.3f}" in text
    row = re.search(rf"^  {re.escape(in_words(r['answer']))}\s+([0-9.]+)$", text, re.M)
    assert row and row.group(1) == f"{p:.3f}"
    assert f"{p:.2f}" in r["message"]
    html = build_templates().env.get_template("diagnosis_result.html").render(v=view(r))     # the page
    assert f'<span id="bdiag-probability">{p:.3f}</span>' in html
    chosen = re.search(r'<tr class="chosen"><td class="strong" title="([^"]+)">[^<]*</td><td class="num">([0-9.]+)</td>',
                       html)
    assert chosen and chosen.group(1) == r["answer"] and chosen.group(2) == f"{p:.3f}"
    assert "-0.0 %" not in html and "-0.0 %" not in text
