"""How numbers and names are written for people: the pages, the condition report and the CLI
share these, so a value reads the same wherever it is shown.

Numbers are plain notation (never ``2.363e+04``), to a stated number of significant figures,
with a true minus sign (U+2212) and thousands separated by a thin comma from 10 000 on. A
parameter is named in words with its symbol beside it ("buffer damping (DO)"), never the symbol
alone; a characteristic such as the trip latch time in words only (its code is the program's). Pure: no I/O.
"""

from __future__ import annotations

import math

from service.mechanics.nomenclature import NAMES, UNITS

MINUS = "−"


def finite(v) -> float | None:
    """``v`` as a finite float, or None (no number, NaN, infinite)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def significant(v, digits: int = 3, *, grouping: bool = False) -> str:
    """``v`` to ``digits`` significant figures in plain notation (3419.9 -> "3420", 3.70406 ->
    "3.70", 23668 -> "23670"), a minus sign for negatives, a dash for no number. ``grouping``
    separates thousands ("23,670") from 10 000 on."""
    v = finite(v)
    if v is None:
        return "—"
    if v == 0:
        return "0"
    decimals = max(0, digits - 1 - math.floor(math.log10(abs(v))))
    rounded = round(v, decimals)
    if rounded == 0:
        return "0"
    text = f"{rounded:,.{decimals}f}" if grouping and abs(rounded) >= 1e4 else f"{rounded:.{decimals}f}"
    return text.replace("-", MINUS)


def compact(v, digits: int = 4) -> str:
    """Like :func:`significant` without trailing zeros, for values written by people (a limit of
    10.1 ms reads "10.1", not "10.10")."""
    text = significant(v, digits, grouping=True)
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return text


def signed_change(rel, decimals: int = 1) -> str:
    """A relative change as a signed percentage ("−5.0 %", "+0.3 %"); one that rounds to zero is
    "0.0 %", never "−0.0 %"."""
    rel = finite(rel)
    if rel is None:
        return "—"
    pct = round(rel * 100, decimals)
    if pct == 0:
        return f"{0:.{decimals}f} %"
    return f"{pct:+.{decimals}f} %".replace("-", MINUS)


def signed_number(v, decimals: int = 2) -> str:
    """A signed number ("+0.42", "−1.30", "0.00": never "−0.00"), a dash for no number."""
    v = finite(v)
    if v is None:
        return "—"
    text = f"{v:+.{decimals}f}"
    return f"{0:.{decimals}f}" if float(text) == 0 else text.replace("-", MINUS)


def unit(name: str) -> str:
    """The unit of parameter ``name`` as shown: "s⁻¹", "s⁻²", or "ratio" for a dimensionless one."""
    u = UNITS.get(name, "")
    return "ratio" if u in ("–", "-", "1") else u


def quantity(v, name_or_unit: str, digits: int = 4) -> str:
    """A value with its unit: ``quantity(24.91, "DO")`` -> "24.91 s⁻¹"; a unit may be given
    directly ("mrad"). A dimensionless parameter is written without a unit word."""
    u = UNITS.get(name_or_unit, name_or_unit)
    text = significant(v, digits, grouping=True)
    return text if text == "—" or u in ("", "–", "-", "1") else f"{text} {u}"


def parameter_name(name: str) -> str:
    """The parameter in words: "buffer damping"; an unknown code is returned as it is."""
    return NAMES.get(name, name)


def is_symbol(name: str) -> bool:
    """``name`` is one of the model's parameter symbols (the paper's AO, BO, ...), which people
    read beside its words; a characteristic's code (``latch_time_s``) is a program's name, not theirs."""
    return name.isalnum() and name.isupper()


def parameter_label(name: str) -> str:
    """The parameter in words with its symbol beside it: "buffer damping (DO)"; a characteristic
    in words alone: "trip latch time"."""
    words = NAMES.get(name)
    if not words:
        return name
    return f"{words} ({name})" if is_symbol(name) else words


def parameter_short(name: str) -> str:
    """The shortest name people read, for an axis: the symbol ("DO"), or a characteristic's words."""
    return name if is_symbol(name) else NAMES.get(name, name)


def plural(n: int, word: str, words: str | None = None) -> str:
    """ "1 alarm", "3 alarms"; ``words`` for an irregular plural."""
    return f"{n:,} {word if n == 1 else (words or word + 's')}"


def watched_words(direction: str) -> str:
    """A watched direction in words: "both" -> "rising or falling"."""
    return {"both": "rising or falling"}.get(direction, direction)
