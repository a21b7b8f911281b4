"""Reading breaker files (TOML) into ``Breaker`` objects: the I/O edge of the mechanics."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from .mechanics.breaker import TABLE2_RANGES, Breaker
from .breaker_travel import TravelMapError, travel_options
from .mechanics.cam_profile import CamProfile, CamProfileError


class BreakerFileError(ValueError):
    """A breaker file is missing, unreadable or inconsistent."""


_SECTIONS = {
    "closing_spring": ("kC", "xC0", "d", "rC", "J1", "theta1_start"),
    "opening_spring": ("kO", "xO0", "xO1", "rO", "J2", "TCf", "TOf"),
    "arc_chamber": ("caec", "raec"),
    "buffer": ("cb", "kb", "rb", "alpha0"),
}
_POSITIVE = ("kC", "xC0", "d", "rC", "J1", "kO", "xO1", "rO", "J2", "raec", "rb", "alpha0")


def load_breaker(path: str | Path) -> Breaker:
    """Load a breaker file; see docs/breaker-file.md for the format."""
    path = Path(path)
    if not path.is_file():
        raise BreakerFileError(f"breaker file not found: {path}")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise BreakerFileError(f"breaker file {path} is not valid TOML: {exc}") from None
    values = {}
    for section, keys in _SECTIONS.items():
        block = data.get(section)
        if not isinstance(block, dict):
            raise BreakerFileError(f"breaker file {path} has no [{section}] section")
        for key in keys:
            v = block.get(key)
            if not isinstance(v, (int, float)) or not np.isfinite(v):
                raise BreakerFileError(f"breaker file {path}: [{section}] {key} must be a number")
            values[key] = float(v)
    for key in _POSITIVE:
        if values[key] <= 0:
            raise BreakerFileError(f"breaker file {path}: {key} must be positive, got {values[key]}")
    cam_block = data.get("cam", {})
    cam_name = cam_block.get("profile")
    if not cam_name and "unknown_design" not in data:  # an unknown design has no cam table
        raise BreakerFileError(f"breaker file {path} has no [cam] profile")
    cam = load_cam_profile(path.parent / cam_name) if cam_name else None
    ranges = dict(TABLE2_RANGES)
    for name, rng in data.get("ranges", {}).items():
        if name not in ranges or len(rng) != 2 or not rng[0] < rng[1]:
            raise BreakerFileError(f"breaker file {path}: bad range for {name}: {rng}")
        ranges[name] = (float(rng[0]), float(rng[1]))
    travel = data.get("travel", {})
    channels = {"travel": "travel", "vibration": "vibration"}
    channels.update({k: str(v) for k, v in data.get("channels", {}).items()})
    stroke = float(travel.get("stroke_rad", cam.stroke if cam else 1.0))
    try:
        extra = travel_options(data, path, stroke, channels["travel"])
    except TravelMapError as exc:
        raise BreakerFileError(str(exc)) from None
    channels["travel"] = extra.pop("travel_channel")
    return Breaker(
        name=str(data.get("name", path.stem)),
        cam=cam,
        stroke=stroke,
        ranges=ranges,
        channels=channels,
        acquisition=dict(data.get("acquisition", {})),
        **extra,
        **values,
    )


def load_cam_profile(path: str | Path) -> CamProfile:
    """Read a cam table CSV with columns ``camshaft_rad,output_shaft_rad``."""
    path = Path(path)
    if not path.is_file():
        raise BreakerFileError(f"cam profile not found: {path}")
    try:
        table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise BreakerFileError(f"cam profile {path} is not a two-column numeric CSV: {exc}") from None
    if table.shape[1] != 2:
        raise BreakerFileError(f"cam profile {path} must have exactly two columns")
    try:
        return CamProfile.from_table(table[:, 0], table[:, 1])
    except CamProfileError as exc:
        raise BreakerFileError(f"cam profile {path}: {exc}") from None
