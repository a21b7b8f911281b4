"""The README reads as a guide (issue 45): short, the tour before the developer material, every
link it gives resolves, and no figure left to fill in."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_is_a_short_guide_with_the_tour_first():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    heads = [line for line in text.splitlines() if line.startswith("## ")]
    assert heads.index("## A five-minute tour") < heads.index("## For developers: `make test`"), heads
    assert text.index("make run") < text.index("make test")
    # `hvcb` is said to live in .venv/bin before it is first used bare
    first_bare = re.search(r"`hvcb [a-z]", text)
    assert first_bare and text.index(".venv/bin") < first_bare.start()
    assert not re.search(r"@[A-Z]+@", text), "a figure was left to be filled in"


def test_every_relative_link_of_the_readme_exists():
    text = README.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", text)
    assert links
    missing = [link for link in links if not (README.parent / link).exists()]
    assert not missing, missing
