"""Writing study outputs: one JSON file, one Markdown table and PNG figures per study.

Every study in ``service.studies`` (and the gap study in ``service.diagnosis``) writes through
these three functions so the output directory always looks the same:
``<out>/<name>.json``, ``<out>/<name>.md`` and ``<out>/<name>_*.png``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np


def _jsonable(value):
    """numpy scalars/arrays -> Python; non-finite floats -> None (strict JSON has no NaN)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(out_dir, name: str, data) -> Path:
    """Write ``data`` to ``<out_dir>/<name>.json`` (directories created) and return the path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.json"
    path.write_text(json.dumps(_jsonable(data), indent=2) + "\n")
    return path


def format_cell(value, digits: int = 4) -> str:
    """A table cell: floats to ``digits`` significant figures, None/NaN as an em dash."""
    if value is None:
        return "—"
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            return "—"
        if v != 0 and (abs(v) >= 1e6 or abs(v) < 1e-3):
            return f"{v:.{digits - 1}e}"
        return f"{v:.{digits}g}"
    return str(value)


def markdown_table(columns: Sequence[str], rows: Sequence[Sequence], digits: int = 4) -> str:
    """A GitHub-flavoured Markdown table."""
    lines = ["| " + " | ".join(str(c) for c in columns) + " |",
             "|" + "|".join("---" for _ in columns) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(format_cell(v, digits) for v in row) + " |")
    return "\n".join(lines)


def write_markdown(out_dir, name: str, title: str, rows=None, columns=None, *,
                   sections: Sequence[tuple] = (), notes: Sequence[str] = (),
                   digits: int = 4) -> Path:
    """Write ``<out_dir>/<name>.md``: a title, an optional main table, further sections.

    Parameters
    ----------
    rows, columns : sequences, optional
        The main table (rows of cells, column headers).
    sections : sequence of (heading, columns, rows)
        Further tables, each under its own ``##`` heading.
    notes : sequence of str
        Paragraphs appended after the tables (method, caveats).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    parts = [f"# {title}", ""]
    if rows is not None and columns is not None:
        parts += [markdown_table(columns, rows, digits), ""]
    for heading, cols, rws in sections:
        parts += [f"## {heading}", "", markdown_table(cols, rws, digits), ""]
    for note in notes:
        parts += [note, ""]
    path = out / f"{name}.md"
    path.write_text("\n".join(parts))
    return path


def new_figure(*args, **kwargs):
    """``plt.subplots`` on the non-interactive Agg backend (safe in workers and on servers)."""
    from service.plots import pyplot

    return pyplot("study figures").subplots(*args, **kwargs)


def save_figure(fig, path) -> Path:
    """Save ``fig`` as PNG at ``path`` (directories created) and close it."""
    from service.plots import pyplot

    plt = pyplot("study figures")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path
