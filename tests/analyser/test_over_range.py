"""Over-range samples inside a sample table (issue 39 item 4): an analyser writes ``∞``, ``-∞``,
``NaN``, ``1.#INF`` or ``OL`` for a reading outside its range. Such samples are missing, not a
refused record: masked on their channel, listed (channel, first and last time, count), the
record stored, and the fit made on a phase whose window holds no masked sample, or refused
in words naming the channel."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drivers.analyser import parse_analyser
from drivers.capture import CaptureError
from drivers.capture_file import load_capture_bytes, read_capture
from drivers.masked import cut, filled, runs
from service.acquisition.capture_file import breaker_reading
from service.breaker_file import load_breaker
from service.cli import main
from service.estimation import fit_capture
from service.estimation.record import operation_capture, upload_operations
from service.estimation.window import FitError
from service.storage.spool import write_capture_file

from .export_gen import Spec, export_text

GENERIC = "config/breakers/generic-analyser.toml"
# Like the three refused field records: three poles wired, one travel over-range for a few
# milliseconds during the opening (trip coil at 305 ms, motion from ~320 ms).
SPAN_MS = (325.0, 327.9)
POLES = (1, 2, 3)


def _text(word="∞", channel=1, span=SPAN_MS, wired=POLES, **kw):
    return export_text(Spec(wired_travel=wired, over_range={channel: (*span, word)}, **kw))


def _capture(text, travel=None):
    b = load_breaker(GENERIC)
    reading = breaker_reading(b)
    if travel is not None:
        reading["travel_channel"] = travel
    return load_capture_bytes(text.encode("utf-8"), name="overrange.csv", **reading), b


@pytest.mark.parametrize("word", ["∞", "-∞", "+∞", "NaN", "nan", "1.#INF", "-1.#IND", "inf", "OL", "-nan(ind)"])
def test_an_over_range_spelling_is_a_masked_sample(word):
    text, _ = _text(word)
    rec = parse_analyser(text, source="f.csv")
    t1 = next(c for c in rec.channels if c.name == "T1")
    spans = t1.masked_spans(rec.sample_rate)
    assert len(spans) == 1 and spans[0]["count"] == 30  # 325.0 .. 327.9 ms at 10 kS/s
    assert spans[0]["first_s"] == pytest.approx(0.325) and spans[0]["last_s"] == pytest.approx(0.3279)
    assert np.isnan(t1.data[3250]) and np.isfinite(t1.data[3249]) and np.isfinite(t1.data[3280])
    assert t1.wired and not t1.over_range_throughout
    t2 = next(c for c in rec.channels if c.name == "T2")
    assert t2.mask is None and np.all(np.isfinite(t2.data))
    assert any("T1 (Contact Travel T1 (mm)): 30 over-range sample(s) masked in 1 span(s): 325.00–327.90 ms" in w
               for w in rec.warnings), rec.warnings


def test_a_word_that_is_no_over_range_mark_is_still_refused_with_line_and_column():
    text, _ = _text("abc")
    with pytest.raises(CaptureError, match=r"f\.csv, line \d+, column 'Contact Travel T1 \(mm\)': 'abc' is not a number"):
        parse_analyser(text, source="f.csv")


def test_masked_runs_fill_and_cut():
    m = np.array([0, 1, 1, 0, 0, 1, 0], bool)
    assert runs(m) == [(1, 2), (5, 5)]
    assert filled([0.0, 9, 9, 3, 4, 9, 6], m).tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    spans = [{"channel": "T1", "first_index": 1, "last_index": 2, "count": 2},
             {"channel": "T1", "first_index": 5, "last_index": 5, "count": 1}]
    assert cut(spans, 2, 5, 10.0) == [{"channel": "T1", "first_index": 0, "last_index": 0, "count": 1,
                                       "first_s": 0.0, "last_s": 0.0}]


def test_the_record_is_read_and_the_valid_phase_fitted():
    """The default choice skips the phase with masked samples; the opening of T2 is fitted."""
    text, truth = _text()
    cap, b = _capture(text)
    assert cap.meta["travel_channel"] == "T2"
    assert any("travel T1 has over-range samples; T2, whose samples are all valid, is fitted instead" in w
               for w in cap.meta["warnings"])
    assert np.all(np.isfinite(cap.travel)) and all(np.all(np.isfinite(a.data)) for a in cap.aux)
    assert [m["channel"] for m in cap.meta["masked"]] == ["T1"] and "over-range samples: T1 30" in cap.flags
    ops = upload_operations(cap, b, None)
    assert [k for _, k in ops] == ["close", "open"]
    close, opening = (c for c, _ in ops)
    assert close.meta["masked"] == [] and not any(f.startswith("over-range") for f in close.flags)
    (span,) = opening.meta["masked"]  # re-indexed to the opening's own first sample
    assert span["count"] == 30 and span["first_s"] == pytest.approx(0.325 - opening.first_sample_index / cap.sample_rate)
    r = fit_capture(opening, b, "open")
    p = truth["params"]
    for name in ("AO", "BO", "DO", "EO"):
        lo, hi = r.ci95[name]
        assert lo < p[name] < hi or abs(r.parameters[name] - p[name]) < 3 * r.stderr[name], name
    assert r.characteristics_record["channel"] == "T2"


def test_a_masked_span_inside_the_window_of_the_chosen_phase_is_refused_in_words():
    text, _ = _text()
    cap, b = _capture(text, travel="T1")
    assert cap.meta["travel_channel"] == "T1"
    opening = operation_capture(cap, b, "open")[0]
    with pytest.raises(FitError) as err:
        fit_capture(opening, b, "open")
    msg = str(err.value)
    assert "travel T1 is over-range (marked ∞ or NaN by the recorder) inside the opening's window" in msg
    assert "T1: 30 samples" in msg and "fit another phase" in msg


def test_a_span_outside_the_window_does_no_harm():
    """Over-range while the breaker rests closed, long after the opening's window."""
    text, truth = _text(span=(380.0, 383.0), length_ms=400)
    cap, b = _capture(text, travel="T1")
    r = fit_capture(cap, b, "open")
    assert abs(r.parameters["BO"] - truth["params"]["BO"]) < 4 * r.stderr["BO"]


def test_a_diagnosis_of_such_a_record_uses_what_is_valid():
    """Issue 42 item 5: a record valid but for its over-range span is diagnosed on what is valid
    (the masked samples are left out of the evidence), no longer refused."""
    from service.diagnosis import diagnose

    text, _ = _text()
    cap, b = _capture(text, travel="T1")
    opening = operation_capture(cap, b, "open")[0]
    r = diagnose([opening], b, "open", next_measurements=False)
    rest, _ = _text(span=(200.0, 202.9))                 # the same record, over-range while at rest
    cap2, _ = _capture(rest, travel="T1")
    clean = diagnose([operation_capture(cap2, b, "open")[0]], b, "open", next_measurements=False)
    assert r["status"] in {"none", "named", "ambiguous", "unexplained"}
    assert r["blocks"] < clean["blocks"]                 # the masked samples are not evidence


def test_a_channel_over_range_throughout_is_refused_in_words():
    text, _ = _text(span=(0.0, 1e4))
    cap, _ = _capture(text)  # T1 has no reading: T2 is fitted, T1 is neither stored nor used
    assert cap.meta["travel_channel"] == "T2" and "T1" not in {a.name for a in cap.aux}
    assert any("T1 (Contact Travel T1 (mm)): every sample is over-range (∞ or NaN): the channel holds no reading"
               in w for w in cap.meta["warnings"])
    with pytest.raises(CaptureError, match="travel channel T1 is over-range throughout .* fit another phase"):
        _capture(text, travel="T1")
    only, _ = _text(span=(0.0, 1e4), wired=(1,))
    with pytest.raises(CaptureError, match="no contact-travel channel is wired .*T1 over-range throughout"):
        _capture(only)


def test_the_spans_survive_the_stored_comtrade(tmp_path):
    text, _ = _text()
    cap, b = _capture(text)
    opening = operation_capture(cap, b, "open")[0]
    path, _ = write_capture_file(opening, tmp_path, "op")
    back = read_capture(path)
    assert back.meta["masked"] == opening.meta["masked"]
    assert main(["inspect", str(path), "--json"]) == 0


def test_inspect_lists_the_masked_spans(tmp_path, capsys):
    text, _ = _text()
    path = tmp_path / "overrange.csv"
    path.write_text(text, encoding="utf-8")
    assert main(["inspect", str(path), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    (m,) = r["masked"]
    assert (m["channel"], m["count"]) == ("T1", 30) and m["first_s"] == pytest.approx(0.325)
    assert r["mapping"]["travel"] == "T2"
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "masked    30 over-range sample(s) in 1 span(s)" in out and "T1: 30 samples, 325.00–327.90 ms" in out


def _shared_example_with(span_ms: tuple) -> str:
    """The shared field-layout example with T1 written '∞' over ``span_ms`` (its one wired pole)."""
    from tests.conftest import shared_dir

    path = shared_dir() / "realworld" / "analyser-csv" / "example-CO-10kHz.csv"
    if not path.is_file():
        pytest.skip(f"the shared analyser example is absent ({path})")
    lines = path.read_text(encoding="utf-8").splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("Coil Current C1 (A)"))
    col = lines[head].split(",").index("Contact Travel T1 (mm)")
    for k in range(int(span_ms[0] * 10), int(span_ms[1] * 10) + 1):  # 10 kS/s: sample k at k/10 ms
        cells = lines[head + 1 + k].split(",")
        cells[col] = "∞"
        lines[head + 1 + k] = ",".join(cells)
    return "\n".join(lines) + "\n"


def test_the_shared_field_example_with_over_range_while_closed_is_stored_and_its_opening_fitted():
    """The field layout (shared example, one pole wired): over-range for 3 ms while the breaker
    rests closed, between the closing and the trip. Both operations are kept, the opening fitted."""
    cap, b = _capture(_shared_example_with((200.0, 202.9)))
    assert cap.meta["travel_channel"] == "T1" and [(m["channel"], m["count"]) for m in cap.meta["masked"]] == [("T1", 30)]
    ops = upload_operations(cap, b, None)
    assert [k for _, k in ops] == ["close", "open"]
    opening = ops[1][0]
    r = fit_capture(opening, b, "open")
    assert r.rmse_rad < 1.5 * r.noise_rad
    for c, _ in ops:  # an operation lists only the spans inside the samples it keeps
        assert all(0 <= m["first_index"] <= m["last_index"] < c.travel.size for m in c.meta["masked"])


def test_the_shared_field_example_with_over_range_in_the_opening_says_why_it_cannot_fit():
    cap, b = _capture(_shared_example_with((320.0, 322.9)))
    ops = upload_operations(cap, b, None)
    assert [k for _, k in ops] == ["close", "open"]  # read and kept whole
    with pytest.raises(FitError, match=r"travel T1 is over-range .* T1: 30 samples"):
        fit_capture(ops[1][0], b, "open")
