"""Issue 38's acceptance on a 10,000-operation history: ``hvcb report`` writes a PDF whose text
holds the breaker, the characteristics with their limits and the active alarms, and whose pages
show the plots; the CSV exports stream in chunks and re-read into the API's numbers.

The history is bulk-inserted once per module (a few seconds); the report's speed and the CSV's
memory are measured in bench/report_speed.py, not asserted here."""

from __future__ import annotations

import csv
import io
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from .conftest import N_HISTORY, REPO

POPPLER = ("pdftotext", "pdftoppm", "pdfimages")
pytestmark = [pytest.mark.history10k,
              pytest.mark.skipif(not all(shutil.which(t) for t in POPPLER),
                                 reason="report lane off: poppler-utils (pdftotext, pdftoppm, pdfimages) not installed")]


def _words(text: str) -> str:
    return re.sub(r"\s+", " ", text)


def _page_text(pdf, page: int) -> str:
    return subprocess.run(["pdftotext", "-f", str(page), "-l", str(page), str(pdf), "-"], check=True,
                          capture_output=True, text=True).stdout


def _blue_fraction(png) -> float:
    """Share of a page's pixels in the plots' blues (value line and band): text is black or grey,
    the table's PASS/FAIL fills green or red, so a page without a plot has none."""
    from PIL import Image

    with Image.open(png) as im:
        a = np.asarray(im.convert("RGB"), dtype=int)
    return float(np.mean((a[..., 2] - a[..., 0] > 40) & (a[..., 2] > 100)))


@pytest.fixture(scope="module")
def report(service10k, tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "Q1.pdf"
    env = {**os.environ, "DATABASE_URL": service10k.url, "HVCB_DATA_DIR": str(service10k.data),
           "PYTHONPATH": str(REPO)}
    run = subprocess.run([sys.executable, "-m", "service.cli", "report", "reference-252kV", "-o", str(out)],
                         cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert f"wrote {out}" in run.stdout
    return out


def test_the_report_holds_the_breaker_the_characteristics_with_limits_and_the_active_alarms(service10k, report):
    from service.display import parameter_label, significant
    from service.storage import crud

    assert report.read_bytes()[:5] == b"%PDF-"
    text = _words(subprocess.run(["pdftotext", "-raw", str(report), "-"], check=True, capture_output=True, text=True).stdout)
    assert "Condition report: reference-252kV" in text
    assert f"{N_HISTORY * 3 // 4:,} openings and {N_HISTORY // 4:,} closings" in text
    with service10k.Session() as s:
        opening = crud.latest_fit(s, breaker_id=1, kind="open")
        closing = crud.latest_fit(s, breaker_id=1, kind="close")
        active = crud.list_alarms(s, state="active", breaker_id=1)
    # the latest opening and closing, each characteristic with its measured value and its limit
    assert f"Operation #{opening.operation_id}," in text and f"Operation #{closing.operation_id}," in text
    t_open = opening.characteristics["operating_time_s"] * 1e3
    assert f"operating time {significant(t_open, 4)} 10.1 to 12.3 ms PASS" in text
    assert (f"average speed {significant(opening.characteristics['average_speed_rad_s'], 4)} 29.4 to 35.9 rad/s "
            "PASS") in text
    assert (f"operating time {significant(closing.characteristics['operating_time_s'] * 1e3, 4)} 25.8 to 31.6 ms "
            "PASS") in text
    assert "overtravel" in text and "damping time" in text
    # the fitted parameters against the [limits] (DO relative to its baseline)
    assert re.search(r"buffer damping \(DO\) \d+\.\d+ [\d.]+ to [\d.]+ ≥ [\d.]+ s⁻¹ (PASS|FAIL)", text)
    # the active alarms: the bulk history's DO leak raised one
    assert active, "the history should leave the DO alarm active"
    assert f"Active now ({len(active)})" in text
    for a in active:
        assert a.message in text
        assert f"#{a.id} {parameter_label(a.parameter)} {a.level.upper()}" in text
    for section in ("Fitted parameters over time", "Prognosis", "Last diagnosis", "Method and version"):
        assert section in text
    assert re.search(r"buffer damping \(DO\) (reaches|is past|is at) its (maintenance )?limit", text, re.IGNORECASE)


def test_the_report_pages_show_the_plots(report, tmp_path):
    listing = subprocess.run(["pdfimages", "-list", str(report)], check=True, capture_output=True, text=True).stdout
    images = [line.split() for line in listing.splitlines()[2:] if line.strip()]
    assert len(images) == 3, listing  # the travel curves, the trends, the prognosis fans
    assert all(int(i[3]) >= 1000 for i in images), listing  # drawn at print resolution (px wide)
    # each embedded figure has ink in its plot area (axes, lines, bands), not a blank canvas
    subprocess.run(["pdfimages", "-png", str(report), str(tmp_path / "image")], check=True)
    for png in sorted(tmp_path.glob("image-*.png")):
        from PIL import Image

        with Image.open(png) as im:
            a = np.asarray(im.convert("L"), dtype=int)
        h, w = a.shape
        plot = a[h // 10:9 * h // 10, w // 10:9 * w // 10]  # inside the margins: the axes' area
        assert np.mean(plot < 200) > 0.02, png.name
    # and the pages as printed show them: the plots' blues are on the figures' pages only
    subprocess.run(["pdftoppm", "-r", "60", "-png", str(report), str(tmp_path / "page")], check=True)
    pages = sorted(tmp_path.glob("page-*.png"))
    blue = {i + 1: _blue_fraction(p) for i, p in enumerate(pages)}
    texts = {i: _page_text(report, i) for i in blue}
    trends = next(i for i, t in texts.items() if "Each fitted parameter with its 95 % interval" in t)
    curves = next(i for i, t in texts.items() if "Travel of the latest opening" in t)
    fans = next(i for i, t in texts.items() if "Projected level of each limited parameter" in t)
    assert blue[trends] > 0.03, blue  # seven panels of lines and bands: a good part of the page
    assert blue[curves] > 3e-4 and blue[fans] > 3e-4, blue  # thin lines on a page of tables
    text_only = [i for i in texts if i not in (trends, curves, fans)]
    assert all(blue[i] < 1e-5 for i in text_only), blue  # the measure sees plots, not text


def test_the_operations_csv_streams_in_chunks(service10k):
    from service.reports.exports import CHUNK_ROWS, operation_chunks

    chunks = list(operation_chunks(service10k.Session, breaker_id=1))
    assert len(chunks) == 1 + -(-N_HISTORY // CHUNK_ROWS)  # the header, then one chunk per query
    assert all(c.count("\r\n") <= CHUNK_ROWS for c in chunks[1:])
    r = service10k.client.get("/api/v1/breakers/reference-252kV/operations.csv", headers=service10k.h())
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert "content-length" not in r.headers  # sent as it is read, never built whole first
    assert 'filename="reference-252kV-operations.csv"' in r.headers["content-disposition"]
    assert r.text == "".join(chunks)
    # the answer leaves as one body message per chunk read, not as one body built first
    with service10k.client.stream("GET", "/api/v1/breakers/reference-252kV/operations.csv",
                                  headers=service10k.h()) as streamed:
        sizes = [len(b) for b in streamed.iter_raw()]
    assert len(sizes) == len(chunks) and max(sizes) < 2 * len(r.content) / (len(chunks) - 1)


def test_the_operations_csv_rereads_into_the_numbers_the_api_gives(service10k):
    c = service10k.client
    r = c.get("/api/v1/breakers/reference-252kV/operations.csv", headers=service10k.h())
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert len(rows) == N_HISTORY
    by_op = {int(row["operation_id"]): row for row in rows}
    units = {"AO": "s^-2", "BO": "s^-2", "DO": "s^-1", "EO": "s^-2", "AC": "s^-2", "BC": "1", "CC": "s^-2"}
    for name, unit in units.items():
        points = c.get(f"/api/v1/breakers/1/parameters?name={name}&limit=20000", headers=service10k.h()).json()["points"]
        assert len(points) in (N_HISTORY * 3 // 4, N_HISTORY // 4)
        for p in points:
            row = by_op[p["operation_id"]]
            assert row["occurred_at [UTC]"] == p["time"]
            assert float(row[f"{name} [{unit}]"]) == p["value"]
            assert [float(row[f"{name}_ci95_low [{unit}]"]), float(row[f"{name}_ci95_high [{unit}]"])] == p["ci95"]
    ops = c.get("/api/v1/breakers/1/operations?limit=1000", headers=service10k.h()).json()
    for op in ops:
        row = by_op[op["id"]]
        assert row["kind"] == op["kind"] and row["occurred_at [UTC]"] == op["occurred_at"]
        chars = op["fit"]["characteristics"]
        assert float(row["operating_time [s]"]) == chars["operating_time_s"]
        assert float(row["average_speed [rad/s]"]) == chars["average_speed_rad_s"]
        assert float(row["overtravel [rad]"]) == chars["overtravel_rad"]
        assert float(row["rmse [rad]"]) == op["fit"]["rmse_rad"]
        other = [k for k in units if k not in op["fit"]["parameters"]]
        assert all(row[f"{k} [{units[k]}]"] == "" for k in other)  # an opening has no closing parameters


def test_the_csv_window_and_the_alarm_history(service10k):
    c = service10k.client
    ops = c.get("/api/v1/breakers/1/operations?limit=1000", headers=service10k.h()).json()
    t = sorted(o["occurred_at"] for o in ops)
    r = c.get("/api/v1/breakers/1/operations.csv",
              params={"from": t[100], "to": t[199]}, headers=service10k.h())
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert [row["occurred_at [UTC]"] for row in rows] == t[100:200]
    alarms = c.get("/api/v1/alarms?state=all&breaker_id=1", headers=service10k.h()).json()
    r = c.get("/api/v1/breakers/reference-252kV/alarms.csv", headers=service10k.h())
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert alarms and [int(x["alarm_id"]) for x in rows] == sorted(a["id"] for a in alarms)
    for a in alarms:
        row = next(x for x in rows if int(x["alarm_id"]) == a["id"])
        assert (row["parameter"], row["level"], row["state"], row["raised_at [UTC]"], row["message"]) == \
            (a["parameter"], a["level"], a["state"], a["raised_at"], a["message"])
        assert float(row["value_at_raise [unit]"]) == a["evidence"]["current"]["value"]


def test_the_report_route_answers_a_pdf_and_refuses_in_words(service10k):
    c = service10k.client
    r = c.get("/api/v1/breakers/reference-252kV/report", params={"from": "2026-01-01"}, headers=service10k.h())
    assert r.status_code == 200 and r.headers["content-type"] == "application/pdf"
    assert r.content[:5] == b"%PDF-"
    r = c.get("/api/v1/breakers/reference-252kV/report", params={"from": "2026-02-01", "to": "2026-01-01"},
              headers=service10k.h())
    assert r.status_code == 422 and "is after its end" in r.json()["detail"]
    r = c.get("/api/v1/breakers/nope/operations.csv", headers=service10k.h())
    assert r.status_code == 404 and "no breaker named 'nope'" in r.json()["detail"]
    assert c.get("/api/v1/breakers/1/alarms.csv").status_code == 401
