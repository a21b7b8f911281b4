"""What the breaker page draws of a breaker diagnosis in the issue-20 shape of the result
(``where``, ``probabilities``, ``rivals``, ``absorbed``, ``next_measurement``, ...), rendered
by the page's own template; every string is escaped."""

from __future__ import annotations

from datetime import datetime, timezone
from types import SimpleNamespace

from service.web.diagnosis_view import view
from service.web.render import build_templates

RESULT = {
    "operation": "open", "captures": [{"source": "a"}, {"source": "b"}, {"source": "c"}],
    "status": "named", "effects": ["viscous_friction", "orifice_buffer"],
    "probabilities": {"none": 0.01, "viscous_friction": 0.93, "orifice_buffer": 0.91, "<b>odd</b>": 0.04},
    "rivals": [{"effect": "sensor_nonlinearity", "probability": 0.05}],
    "absorbed": [{"effect": "puffer_gas", "parameter_bias": {"DO": 0.021}}],
    "where": [{"phase": "acceleration", "t0_s": 0.0, "t1_s": 0.01, "gap_before": 1.2, "gap_after": 1.0},
              {"phase": "buffer_engagement", "t0_s": 0.01, "t1_s": 0.02, "gap_before": 4.0, "gap_after": 1.1}],
    "gap": {"before_rms_rad": 3.0e-3, "after_rms_rad": 1.6e-3, "noise_rad": 1.5e-3, "shrink": 0.9},
    "reduced_parameters": {"AO": 3400.0, "DO": 41.0},
    "corrected_parameters": {"AO": 3420.0, "DO": 39.5},
    "next_measurement": [{"measurement": "10 openings below 0 °C", "expected_delta_bic": -14.2,
                          "separates": ["viscous_friction", "orifice_buffer"]}],
    "message": "two effects at once",
    "answer": "orifice_buffer+viscous_friction", "answer_probability": 0.9, "mild": ["sensor_nonlinearity"],
}


def test_view_reads_the_issue_20_shape():
    v = view(RESULT)
    assert v["status"] == "named" and v["effects"] == ["viscous_friction", "orifice_buffer"]
    assert [p[0] for p in v["probabilities"]][:2] == ["viscous_friction", "orifice_buffer"]  # most probable first
    assert v["far"] == {"before": 3.0e-3, "after": 1.6e-3, "noise": 1.5e-3, "shrink": 0.9}
    # the longest bar (4× noise) is the full width; the noise floor sits at a quarter of it
    assert v["where"][1]["before_px"] == 250.0 and v["bars"]["noise_px"] == 62.5
    assert v["where"][1]["after_px"] == round(1.1 * 62.5, 1)
    assert v["params"]["corrected"] and v["params"]["n"] == 1
    ao, do = v["params"]["rows"]
    assert (ao["name"], ao["reduced"], ao["corrected"]) == ("AO", 3400.0, 3420.0) and ao["lo"] is None
    assert abs(do["change"] - (39.5 - 41.0) / 41.0) < 1e-12
    assert v["next"][0]["separates"] == ["viscous_friction", "orifice_buffer"]
    assert v["absorbed"] == [{"effect": "puffer_gas", "bias": {"DO": 0.021}, "bias_text": ["DO +2.1 %"]}]
    assert v["words"]["viscous_friction"] == "viscous bearing friction"


def test_parameters_of_several_captures_are_summarised_and_an_unchanged_correction_is_dropped():
    reduced = [{"AO": 3400.0, "DO": 40.0}, {"AO": 3420.0, "DO": 42.0}]
    v = view({"status": "none", "reduced_parameters": reduced, "corrected_parameters": [dict(d) for d in reduced]})
    ao = v["params"]["rows"][0]
    assert (ao["reduced"], ao["lo"], ao["hi"]) == (3410.0, 3400.0, 3420.0)
    assert not v["params"]["corrected"] and ao["corrected"] is None
    v = view({"status": "named", "reduced_parameters": reduced,
              "corrected_parameters": [{"AO": 3300.0, "DO": 40.0}, {"AO": 3320.0, "DO": 42.0}]})
    ao = v["params"]["rows"][0]
    assert v["params"]["corrected"] and ao["corrected"] == 3310.0 and abs(ao["change"] + 100 / 3410) < 1e-12


def test_view_takes_what_is_there():
    v = view({"status": "none"})
    assert v["status"] == "none" and v["effects"] == [] and v["where"] == [] and v["next"] == []
    assert v["far"]["before"] is None and not v["params"]["corrected"]
    assert view(None) is None and view("garbage") is None


def test_template_draws_every_part_escaped():
    env = build_templates().env
    row = SimpleNamespace(id=7, status="done", operation="open", last_n=3, operation_ids=[1, 2, 3],
                          requested_at=datetime(2026, 11, 25, tzinfo=timezone.utc), started_at=None,
                          requested_by="<script>x()</script>", failure_reason=None)
    html = env.get_template("breaker_diagnosis.html").render(
        b=SimpleNamespace(id=1), csrf="tok", bdiag=row, bdiag_summary="3 stored openings used of the last 3",
        bdiag_view=view(RESULT), bdiag_recent=[row], DIAG_MIN=2, DIAG_MAX=20)
    assert "<script>" not in html and "&lt;script&gt;x()&lt;/script&gt;" in html
    assert "<b>odd</b>" not in html and "&lt;b&gt;odd&lt;/b&gt;" in html
    assert html.count('class="bar bar-before"') == 2 and html.count('class="bar-after"') == 2
    assert "10 openings below 0 °C" in html and "−14.2" in html
    assert 'Rivals: <span title="sensor_nonlinearity">travel-sensor nonlinearity</span> (0.050)' in html
    assert 'title="puffer_gas">puffer gas compression' in html and "two effects at once" in html
    assert "DO +2.1 %" in html and "-0.0 %" not in html
    assert ('title="orifice_buffer+viscous_friction">orifice buffer (damping ∝ speed²) + viscous bearing friction'
            '</strong></span><span class="small"> (probability <span id="bdiag-probability">0.900</span>') in html
    assert "Present but mild" not in html          # no size gate: materiality is a flag beside the answer
    assert 'id="bdiag-before">3.000<' in html and 'id="bdiag-after">1.600<' in html
    assert "<th>Corrected</th>" in html and "bdiag-no-correction" not in html
    assert "-3.7 %" in html  # DO 41.0 -> 39.5
    assert 'name="csrf_token" value="tok"' in html
