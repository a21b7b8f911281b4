"""What a breaker analyser's CSV export looks like, as data: a :class:`Profile`.

A profile says how to recognise the layout by its content (the table's column names), which
header keys are metadata, the sampling rate or the analyser's own results, which lines carry the
per-channel velocities, and which column names are which channel kind in which unit. One
generic parser (``drivers.analyser.parser``) reads every profile; another analyser's export is
a new ``Profile`` value in ``drivers/analyser/profiles.py``, not new parsing code.

Header keys are matched after :func:`normalise_key` (whitespace collapsed, one space either
side of a dash), case-insensitively, against the whole key (``re.fullmatch``). A pattern's
named group ``ch`` (``T1``, ``C4`` ...) files the value under that channel.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

# Channel kinds, and the unit each is delivered in (what the Capture's auxiliary channels hold).
TRAVEL, COIL, RESISTANCE, DCRM_CURRENT = "travel", "coil_current", "resistance", "dcrm_current"
KIND_UNITS = {TRAVEL: "mm", COIL: "A", RESISTANCE: "µΩ", DCRM_CURRENT: "A"}


@dataclass(frozen=True)
class Column:
    """Column names matching ``pattern`` (fullmatch, case-insensitive; group ``n`` = channel
    number) are channels of ``kind``, named ``name.format(n=...)``, whose values are in ``unit``;
    ``factor`` converts them to the kind's unit in ``KIND_UNITS``."""

    pattern: str
    kind: str
    name: str
    unit: str
    factor: float = 1.0


@dataclass(frozen=True)
class HeaderValue:
    """A header key (``pattern``) whose value is kept as ``name`` (per channel with group ``ch``):
    a number in ``unit`` when ``unit`` is set, a date (ISO 8601) when ``date``, else text.
    A value that is not what it should be is kept as written and flagged
    (``drivers.analyser.values``)."""

    pattern: str
    name: str
    unit: str | None = None
    date: bool = False


@dataclass(frozen=True)
class Profile:
    """One analyser's export layout.

    Attributes
    ----------
    name : str
        Shown by ``hvcb inspect`` (``format``).
    recognise : tuple of str
        Regexes that must all match (search) one line: that line is the table's column names.
        Content, not the file name, decides the layout.
    columns : tuple of Column
    rate : dict
        Header key pattern -> factor to Hz (the stated sampling rate).
    metadata : tuple of HeaderValue
        Station, breaker, settings: kept as they are.
    results : tuple of HeaderValue
        The analyser's own results (travel, velocities, over-travel, rebound, coil currents).
    velocity_lines : tuple of HeaderValue
        Lines between the header and the table whose k-th value belongs to the k-th travel
        channel (pattern = the repeated key).
    plot_length : str or None
        Header key pattern of the record length [ms], cross-checked against the sample count.
    stated_stroke : tuple of str
        Result/metadata names (per travel channel, in mm) that state the contact stroke, most
        trusted first; 0 means "not stated".
    header_lines_max : int
        The column-name line is searched for in this many first lines.
    day_first : bool
        Whether ``01/02/2026`` is the 1st of February (the analyser's locale); a part above 12
        decides regardless.
    """

    name: str
    recognise: tuple
    columns: tuple
    rate: dict = field(default_factory=dict)
    metadata: tuple = ()
    results: tuple = ()
    velocity_lines: tuple = ()
    plot_length: str | None = None
    stated_stroke: tuple = ()
    header_lines_max: int = 400
    day_first: bool = True

    def recognises(self, line: str) -> bool:
        return all(re.search(p, line, re.IGNORECASE) for p in self.recognise)


def normalise_key(key: str) -> str:
    """``'Open -Rebound(T1)(mm) :'`` -> ``'Open - Rebound(T1)(mm)'``."""
    key = key.strip().rstrip(":").strip()
    key = re.sub(r"\s*-\s*", " - ", key)
    return re.sub(r"\s+", " ", key).strip()
