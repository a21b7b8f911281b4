"""The breaker file's ``[travel]`` mapping of a contact travel recorded in mm (a breaker
analyser's transducer on the linkage) to the model's coordinate, and its ``[unknown_design]``
section. Kept apart from ``breaker_file`` so that file only calls :func:`travel_options`.

    [travel]
    stroke_rad = 1.0          # open rest position, rad from closed (the model's stroke)
    record_unit = "mm"        # the contact travel as the analyser records it
    record_zero = "open"      # the record's 0 mm is the open position (travel rises on closing)
    mm_per_rad = 120.0        # a linear linkage: contact mm per output-shaft rad, or "record":
                              #   the record's stroke [mm] / stroke_rad
    # table = "linkage.csv"   # instead of mm_per_rad: columns contact_mm,shaft_rad, both from
                              #   the record's zero position, monotonic (a non-linear linkage)

    [unknown_design]          # a breaker whose design is not known
    estimate = ["alpha0", "CO"]  # structure the opening fit estimates from the curve itself

The model's travel is rad from closed; ``record_zero = "open"`` flips it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


LENGTH_UNITS = {"mm": 1.0, "m": 1e3, "cm": 10.0}  # to mm
ESTIMABLE = ("alpha0", "CO")


class TravelMapError(ValueError):
    pass


@dataclass(frozen=True)
class TravelMap:
    """Contact travel [mm from ``zero``] <-> output-shaft angle [rad from closed].

    Either ``mm_per_rad`` (a number; None with ``from_record`` = the record's stroke sets it)
    or a monotonic table ``table_mm`` -> ``table_rad`` (both from the record's zero).
    """

    stroke_rad: float
    zero: str = "open"
    mm_per_rad: float | None = None
    from_record: bool = False
    table_mm: tuple = ()
    table_rad: tuple = ()

    def to_rad(self, values, unit: str, stated_stroke_mm: float | None):
        """``(travel [rad from closed], info)`` for a travel recorded in ``unit``; ``info`` (JSON)
        keeps the points mapping rad back to mm and the stroke used."""
        key = unit.strip().lower()
        if key not in LENGTH_UNITS:
            raise ValueError(f"the travel is in '{unit}'; the breaker's [travel] maps {', '.join(LENGTH_UNITS)}")
        mm = np.asarray(values, dtype=float) * LENGTH_UNITS[key]
        note = None
        if self.table_mm:
            from_zero = np.interp(mm, self.table_mm, self.table_rad, left=np.nan, right=np.nan)
            lo, hi = self.table_mm[0], self.table_mm[-1]
            outside = ~np.isfinite(from_zero)
            if outside.any():
                # Extrapolate linearly with the end slopes: over-travel runs past the table.
                s0 = (self.table_rad[1] - self.table_rad[0]) / (self.table_mm[1] - self.table_mm[0])
                s1 = (self.table_rad[-1] - self.table_rad[-2]) / (self.table_mm[-1] - self.table_mm[-2])
                from_zero = np.where(mm < lo, self.table_rad[0] + (mm - lo) * s0, from_zero)
                from_zero = np.where(mm > hi, self.table_rad[-1] + (mm - hi) * s1, from_zero)
            pts_mm = list(self.table_mm)
            pts_rad = list(self.table_rad)
            stroke_mm = float(np.interp(self.stroke_rad, self.table_rad, self.table_mm))
            ratio = None
        else:
            if self.from_record:
                stroke_mm, note = (stated_stroke_mm, "stated in the record's header") if stated_stroke_mm \
                    else (record_stroke_mm(mm), "measured from the record's rest levels")
                if not stroke_mm or stroke_mm <= 0:
                    raise ValueError("the record states no stroke and its travel shows no motion to measure one")
                ratio = stroke_mm / self.stroke_rad
            else:
                ratio = float(self.mm_per_rad)
                stroke_mm = ratio * self.stroke_rad
            from_zero = mm / ratio
            pts_mm, pts_rad = [0.0, stroke_mm], [0.0, self.stroke_rad]
        rad = self.stroke_rad - from_zero if self.zero == "open" else from_zero
        # Points as (rad from closed, mm as recorded), for converting model angles back to mm.
        if self.zero == "open":
            back = {"rad": [self.stroke_rad - r for r in pts_rad], "mm": pts_mm}
        else:
            back = {"rad": pts_rad, "mm": pts_mm}
        order = np.argsort(back["rad"])
        info = {"rad": [float(back["rad"][i]) for i in order], "mm": [float(back["mm"][i]) for i in order],
                "zero": self.zero, "stroke_mm": float(stroke_mm), "mm_per_rad": ratio,
                "stroke_source": note or "breaker file"}
        return rad, info


def record_stroke_mm(mm: np.ndarray) -> float:
    """Stroke [mm] from the rest levels of a record: the level of its first resting stretch to
    the resting level farthest from it (a CO or O-CO record rests at both ends of the stroke)."""
    mm = np.asarray(mm, dtype=float)
    n = max(mm.size // 100, 8)
    k = mm.size // n
    if k < 2:
        return float(np.ptp(mm))
    blocks = mm[: k * n].reshape(k, n)
    spread = np.ptp(blocks, axis=1)
    quiet = spread <= np.percentile(spread, 25) * 3 + 1e-12
    levels = np.median(blocks, axis=1)[quiet]
    if levels.size < 2:
        return float(np.ptp(mm))
    return float(np.max(np.abs(levels - levels[0])))


def mm_at(info: dict, rad):
    """The record's mm at model travel ``rad`` [rad from closed] (``info`` from ``to_rad``)."""
    r, m = np.asarray(info["rad"]), np.asarray(info["mm"])
    return np.interp(rad, r, m, left=None, right=None) if r.size > 2 else \
        m[0] + (np.asarray(rad, dtype=float) - r[0]) * (m[1] - m[0]) / (r[1] - r[0])


def travel_options(data: dict, path: Path, stroke_rad: float, channel: str) -> dict:
    """From a breaker file's parsed TOML: ``travel_channel`` (the name), ``travel_map`` (the mm
    mapping when ``[travel]`` has one: its ``to_rad`` goes to the capture reader explicitly)
    and ``estimate_structure``."""
    travel = data.get("travel", {})
    if not isinstance(travel, dict):
        raise TravelMapError(f"breaker file {path}: [travel] must be a table")
    unknown = data.get("unknown_design", {})
    estimate = tuple(unknown.get("estimate", ())) if isinstance(unknown, dict) else ()
    bad = [e for e in estimate if e not in ESTIMABLE]
    if bad:
        raise TravelMapError(f"breaker file {path}: [unknown_design] estimate can hold {', '.join(ESTIMABLE)}, "
                             f"not {', '.join(map(str, bad))}")
    out = {"travel_channel": channel, "travel_map": None, "estimate_structure": estimate}
    if "record_unit" not in travel and "mm_per_rad" not in travel and "table" not in travel:
        return out
    unit = str(travel.get("record_unit", "mm")).strip().lower()
    if unit not in LENGTH_UNITS:
        raise TravelMapError(f"breaker file {path}: [travel] record_unit must be one of {', '.join(LENGTH_UNITS)}")
    zero = str(travel.get("record_zero", "open")).strip().lower()
    if zero not in ("open", "closed"):
        raise TravelMapError(f"breaker file {path}: [travel] record_zero must be \"open\" or \"closed\", got {zero!r}")
    ratio, table = travel.get("mm_per_rad"), travel.get("table")
    if (ratio is None) == (table is None):
        raise TravelMapError(f"breaker file {path}: [travel] needs exactly one of mm_per_rad (a linear "
                             "linkage, or \"record\") and table (a CSV contact_mm,shaft_rad)")
    if table is not None:
        tm, tr = _load_table(Path(path).parent / str(table), path)
        tmap = TravelMap(stroke_rad, zero, table_mm=tuple(tm), table_rad=tuple(tr))
    elif isinstance(ratio, str) and ratio.strip().lower() == "record":
        tmap = TravelMap(stroke_rad, zero, from_record=True)
    elif isinstance(ratio, (int, float)) and np.isfinite(ratio) and ratio > 0:
        tmap = TravelMap(stroke_rad, zero, mm_per_rad=float(ratio))
    else:
        raise TravelMapError(f"breaker file {path}: [travel] mm_per_rad must be a positive number or "
                             f"\"record\", got {ratio!r}")
    out["travel_map"] = tmap
    return out


def _load_table(file: Path, path):
    if not file.is_file():
        raise TravelMapError(f"breaker file {path}: [travel] table {file} not found")
    try:
        t = np.loadtxt(file, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise TravelMapError(f"linkage table {file} is not a two-column numeric CSV: {exc}") from None
    if t.shape[1] != 2 or t.shape[0] < 2:
        raise TravelMapError(f"linkage table {file} needs two columns (contact_mm,shaft_rad) and two rows or more")
    if not (np.all(np.diff(t[:, 0]) > 0) and np.all(np.diff(t[:, 1]) > 0)):
        raise TravelMapError(f"linkage table {file} must increase in both columns (a monotonic linkage)")
    return t[:, 0].tolist(), t[:, 1].tolist()
