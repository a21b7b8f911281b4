"""What an engineer must never read on a page or in the report (issue 45): configuration words,
program identifiers, computer number formats and placeholders, and numbers without their unit."""

from __future__ import annotations

import re

# Each: what it catches, and why it is not for an engineer.
FORBIDDEN = [
    (re.compile(r"\b(?:min|max)_change\b"), "a breaker-file expression"),
    (re.compile(r"\b[A-Za-z]+_[A-Za-z0-9_]+\b"), "an identifier with '_' inside a word"),
    (re.compile(r"\d[eE][+−-]?0\d"), "a number in e-notation"),
    (re.compile(r"--"), "a double hyphen (a placeholder or a missing value)"),
    (re.compile(r"\bNone\b"), "Python's None"),
    (re.compile(r"\bNaN\b|\bnan\b"), "NaN"),
]


def word_problems(text: str) -> list[str]:
    """Every forbidden word in ``text``, with the line it is on."""
    out = []
    for line in text.splitlines():
        for pattern, why in FORBIDDEN:
            for m in pattern.finditer(line):
                out.append(f"{why}: {m.group(0)!r} in {line.strip()[:140]!r}")
    return out
