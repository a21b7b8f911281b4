"""D10: breaker input is validated (identifier names, physical ranges, plain cam file names,
size and nesting caps) and refused with 422 in words, never a 500."""

from __future__ import annotations

import re

import pytest

from service.breaker_file import BreakerFileError, breaker_from_text

from .conftest import BREAKER_FILE

TEXT = BREAKER_FILE.read_text().replace('name = "reference-252kV"', 'name = "bay-new"')
CAM = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()


def _set(text: str, key: str, value: str) -> str:
    return re.sub(rf"(?m)^{key}\s*=.*$", f"{key} = {value}", text)


BAD = {
    "nested 5,000 deep": ("x = " + "[" * 5000 + "]" * 5000 + "\n" + TEXT, "nested too deeply"),
    "empty name": (_set(TEXT, "name", '""'), "name"),
    "100,000-character name": (_set(TEXT, "name", '"' + "n" * 100_000 + '"'), "name"),
    "path as name": (_set(TEXT, "name", '"../../x"'), "name"),
    "markup as name": (_set(TEXT, "name", "'<b>x</b>'"), "name"),
    "negative stroke": (_set(TEXT, "stroke_rad", "-1"), "stroke_rad"),
    "zero sample rate": (_set(TEXT, "sample_rate_hz", "0"), "sample_rate_hz"),
    "1e12 sample rate": (_set(TEXT, "sample_rate_hz", "1e12"), "sample_rate_hz"),
    "cam path outside": (_set(TEXT, "profile", '"../../etc/passwd"'), "profile"),
    "negative stiffness": (_set(TEXT, "kO ", "-130e3"), "kO"),
    "NaN inertia": (_set(TEXT, "J2 ", "nan"), "J2"),
    "unknown key": (TEXT.replace("[buffer]\n", "[buffer]\ncolour = 1\n"), "colour"),
    "missing section": (re.sub(r"(?ms)^\[arc_chamber\].*?(?=^\[)", "", TEXT), "arc_chamber"),
    "bad range": (TEXT.replace("DO = [10.0, 50.0]", "DO = [50.0, 10.0]"), "DO"),
    "no name": (re.sub(r'(?m)^name = .*$', "", TEXT), "name"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_breaker_files_are_422_in_words_over_the_api(env, case):
    text, word = BAD[case]
    r = env.client.post("/api/v1/breakers", json={"breaker_file": text, "cam_table": CAM}, headers=env.h())
    assert r.status_code == 422, (case, r.status_code, r.text[:300])
    detail = r.json()["detail"]
    assert isinstance(detail, str) and word in detail, (case, detail[:300])
    assert "Traceback" not in detail and "RecursionError" not in detail


def test_the_reference_file_still_loads_and_registers(env):
    b = breaker_from_text(TEXT, CAM)
    assert b.name == "bay-new" and b.channels == {"travel": "travel", "vibration": "vibration"}
    assert b.acquisition["sample_rate_hz"] == 128000
    r = env.client.post("/api/v1/breakers", json={"breaker_file": TEXT, "cam_table": CAM}, headers=env.h())
    assert r.status_code == 201, r.text


def test_file_errors_name_the_file_and_the_key():
    with pytest.raises(BreakerFileError) as err:
        breaker_from_text(_set(TEXT, "xC0", "-0.37"), CAM, source="bays/q1.toml")
    assert "bays/q1.toml" in str(err.value) and "[closing_spring] xC0" in str(err.value)
