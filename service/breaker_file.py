"""Reading breaker files (TOML) into ``Breaker`` objects: the I/O edge of the mechanics.

The file is validated by a pydantic model (``BreakerFileModel``) built from its text, so a
file on disk, a breaker stored in the database and one sent to the API are read the same way,
without a temporary folder. Every number has a physical range (docs/breaker-file.md); the
name is an identifier; the text is capped in size and TOML nesting depth.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model, field_validator, model_validator

from .breaker_limits import CharacteristicLimits, Limits, ParameterLimit
from .breaker_travel import TravelMapError, travel_options
from .mechanics.breaker import TABLE2_RANGES, Breaker
from .mechanics.cam_profile import CamProfile, CamProfileError
from .mechanics.effects import EFFECT_NAMES, PHYSICAL_UPPER, REFERENCE_STRENGTHS, SIGNED

MAX_TEXT_BYTES = 200_000       # a breaker file is a page of TOML; the API refuses more
MAX_CAM_BYTES = 5_000_000      # a cam table of ~100,000 rows
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9 _.:-]{0,79}$"  # shown in pages and SCADA names: no paths, no markup
FILE_NAME_PATTERN = r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,120}$"  # a plain file name beside the breaker file
CHANNEL_PATTERN = r"^[^\x00-\x1f\x7f]{1,64}$"


class BreakerFileError(ValueError):
    """A breaker file is missing, unreadable or inconsistent."""


def _num(lo: float, hi: float, *, lo_open: bool = True, desc: str = ""):
    """A finite float in (lo, hi] (or [lo, hi] when ``lo_open`` is false)."""
    bound = {"gt": lo} if lo_open else {"ge": lo}
    return Annotated[float, Field(le=hi, allow_inf_nan=False, description=desc, **bound)]


# Physical ranges: wide enough for any spring-operated mechanism from 12 kV to 1100 kV (the
# reference 252 kV breaker sits two to three decades inside each), narrow enough to refuse a
# typo of orders of magnitude or a sign. Lengths [m], stiffness [N/m], inertia [kg m^2].
Stiffness = _num(0.0, 1e9, desc="N/m")
Length = _num(0.0, 5.0, desc="m")
Arm = _num(0.0, 2.0, desc="m")
Inertia = _num(0.0, 1e3, desc="kg m^2")
Torque = _num(0.0, 1e6, lo_open=False, desc="N m")
Damping = _num(0.0, 1e8, lo_open=False, desc="N s/m")
Angle = Annotated[float, Field(ge=-2 * math.pi, le=2 * math.pi, allow_inf_nan=False, description="rad")]
LengthOrZero = _num(0.0, 5.0, lo_open=False, desc="m")
StiffnessOrZero = _num(0.0, 1e9, lo_open=False, desc="N/m")
PositiveAngle = _num(0.0, 2 * math.pi, desc="rad")
SampleRate = _num(100.0, 10e6, lo_open=False, desc="Hz")
FullScale = _num(0.0, 4 * math.pi, desc="rad")
Acceleration = _num(0.0, 1e5, desc="g")
Fraction = Annotated[float, Field(gt=0.0, lt=1.0)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ClosingSpring(_Section):
    kC: Stiffness
    xC0: Length
    d: Length
    rC: Arm
    J1: Inertia
    theta1_start: Angle


class OpeningSpring(_Section):
    kO: Stiffness
    xO0: LengthOrZero
    xO1: Length
    rO: Arm
    J2: Inertia
    TCf: Torque
    TOf: Torque


class ArcChamber(_Section):
    caec: Damping
    raec: Arm


class Buffer(_Section):
    cb: Damping
    kb: StiffnessOrZero
    rb: Arm
    alpha0: PositiveAngle


class Cam(_Section):
    profile: str = Field(pattern=FILE_NAME_PATTERN, description="cam table CSV beside the breaker file")


class Travel(_Section):
    """The model's stroke, and how a contact travel recorded in mm maps to it (breaker_travel)."""

    stroke_rad: PositiveAngle | None = None
    record_unit: str | None = Field(None, max_length=8)
    record_zero: str | None = Field(None, max_length=8)
    mm_per_rad: float | str | None = None
    table: str | None = Field(None, pattern=FILE_NAME_PATTERN, description="linkage CSV beside the breaker file")


class UnknownDesign(_Section):
    estimate: list[str] = Field(default_factory=list, max_length=8)


class Channels(_Section):
    travel: str = Field("travel", pattern=CHANNEL_PATTERN)
    vibration: str = Field("vibration", pattern=CHANNEL_PATTERN)
    temperature: str | None = Field(None, pattern=CHANNEL_PATTERN, description="ambient/mechanism [C]")


class Acquisition(_Section):
    sample_rate_hz: SampleRate | None = None
    travel_full_scale_rad: FullScale | None = None
    vibration_full_scale_g: Acceleration | None = None
    shock_threshold_g: Acceleration | None = None
    motion_fraction: Fraction | None = None


class VibrationLimits(_Section):
    """``[vibration]``: the trip latch's maintenance limit (service.vibration's latch time: the
    vibration's first shock to the start of motion). ``latch_time_max_ms`` [ms]: the prognosis
    forecasts when the latch time reaches it, as ``[limits] latch_time_s = { max = ... }`` would in s."""

    latch_time_max_ms: float | None = Field(None, gt=0.0, le=100.0, allow_inf_nan=False,
                                            description="trip latch time limit [ms]")


def _effects_section():
    """``[effects]``: how strong each catalogued effect typically is on this breaker [-] (the
    diagnosis's fit scale and its "absorbed" check); each within the catalogue's physical bound,
    negative only for the signed families. Unnamed effects keep the reference breaker's."""
    fields = {}
    for name in EFFECT_NAMES:
        hi = PHYSICAL_UPPER[name]
        fields[name] = (float | None, Field(None, ge=-hi if name in SIGNED else 0.0, le=hi, allow_inf_nan=False))
    return create_model("EffectStrengths", __base__=_Section, **fields)


EffectStrengths = _effects_section()


class BreakerFileModel(BaseModel):
    """A breaker file's content. A new section is one more field here (its own model)."""

    model_config = ConfigDict(extra="forbid")
    name: str | None = Field(None, pattern=NAME_PATTERN)
    closing_spring: ClosingSpring
    opening_spring: OpeningSpring
    arc_chamber: ArcChamber
    buffer: Buffer
    cam: Cam | None = None  # required but for an [unknown_design] (no cam table: no closing model)
    unknown_design: UnknownDesign | None = None
    travel: Travel = Field(default_factory=Travel)
    channels: Channels = Field(default_factory=Channels)
    acquisition: Acquisition = Field(default_factory=Acquisition)
    ranges: dict[str, tuple[float, float]] = Field(default_factory=dict)
    limits: Limits = Field(default_factory=Limits)  # maintenance limits (service/breaker_limits.py)
    # accepted ranges of the travel characteristics: the condition report's pass/fail (docs/reports.md)
    characteristic_limits: CharacteristicLimits = Field(default_factory=CharacteristicLimits)
    effects: EffectStrengths = Field(default_factory=EffectStrengths)
    # the trip latch's limit in ms (service.vibration), folded into [limits] as latch_time_s [s]
    vibration: VibrationLimits = Field(default_factory=VibrationLimits)

    @model_validator(mode="after")
    def _latch_limit(self):
        ms = self.vibration.latch_time_max_ms
        if ms is not None:
            if "latch_time_s" in self.limits.root:
                raise ValueError("the latch time's limit is given twice: keep [vibration] latch_time_max_ms (ms) "
                                 "or [limits] latch_time_s (s), not both")
            self.limits.root["latch_time_s"] = ParameterLimit(max=ms / 1000.0)
        return self

    @model_validator(mode="after")
    def _cam_or_unknown(self):
        if self.cam is None and self.unknown_design is None:
            raise ValueError("[cam] profile is missing (only an [unknown_design] breaker goes without one)")
        return self

    @field_validator("ranges")
    @classmethod
    def _ranges(cls, v):
        for name, (lo, hi) in v.items():
            if name not in TABLE2_RANGES:
                raise ValueError(f"unknown parameter {name!r} (known: {', '.join(TABLE2_RANGES)})")
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"bad range for {name}: [{lo}, {hi}] (need two finite numbers, low < high)")
        return v


def _words(exc: ValidationError) -> str:
    """pydantic's errors as one line: ``[section] key: what is wrong``."""
    parts = []
    for e in exc.errors()[:5]:
        loc = [str(p) for p in e.get("loc", ())]
        where = (f"[{loc[0]}] " + ".".join(loc[1:]) if len(loc) > 1 else (loc[0] if loc else "file")).strip()
        msg = e.get("msg", "invalid").removeprefix("Value error, ")
        if e.get("type") == "missing":
            msg = "is missing" if len(loc) > 1 else "section is missing"
        elif e.get("type") == "extra_forbidden":
            msg = "is not a known key or section"
        parts.append(f"{where}: {msg}")
    more = len(exc.errors()) - 5
    return "; ".join(parts) + (f" (and {more} more)" if more > 0 else "")


def parse_breaker_text(text: str, *, source: str) -> BreakerFileModel:
    """The validated content of a breaker file's text; ``source`` names it in messages."""
    if len(text.encode("utf-8", "replace")) > MAX_TEXT_BYTES:
        raise BreakerFileError(f"breaker file {source} is larger than {MAX_TEXT_BYTES} bytes")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise BreakerFileError(f"breaker file {source} is not valid TOML: {exc}") from None
    except RecursionError:
        raise BreakerFileError(f"breaker file {source} is nested too deeply to be a breaker file") from None
    try:
        return BreakerFileModel.model_validate(data)
    except ValidationError as exc:
        raise BreakerFileError(f"breaker file {source}: {_words(exc)}") from None
    except RecursionError:
        raise BreakerFileError(f"breaker file {source} is nested too deeply to be a breaker file") from None


def breaker_from_text(text: str, cam_table: str, *, source: str = "(text)", default_name: str = "breaker") -> Breaker:
    """A ``Breaker`` from a breaker file's text and its cam table's text (the API and the
    database hold both as text)."""
    model = parse_breaker_text(text, source=source)
    cam = cam_profile_from_text(cam_table, source=model.cam.profile) if model.cam is not None else None
    return _build(model, cam, default_name=default_name, source=source, folder=None)


def _build(model: BreakerFileModel, cam: CamProfile | None, *, default_name: str, source,
           folder: Path | None) -> Breaker:
    """``folder``: where files the breaker file names live (a linkage table); None for text."""
    values = {**model.closing_spring.model_dump(), **model.opening_spring.model_dump(),
              **model.arc_chamber.model_dump(), **model.buffer.model_dump()}
    ranges = dict(TABLE2_RANGES)
    ranges.update({k: (float(lo), float(hi)) for k, (lo, hi) in model.ranges.items()})
    stroke = model.travel.stroke_rad
    stroke = float(stroke if stroke is not None else (cam.stroke if cam is not None else 1.0))
    channels = model.channels.model_dump(exclude_none=True)
    sections = {"travel": model.travel.model_dump(exclude_none=True)}
    if model.unknown_design is not None:
        sections["unknown_design"] = model.unknown_design.model_dump()
    try:
        extra = travel_options(sections, (folder or Path(".")) / str(source), stroke, channels["travel"])
    except TravelMapError as exc:
        raise BreakerFileError(str(exc)) from None
    channels["travel"] = extra.pop("travel_channel")
    return Breaker(
        name=model.name or default_name,
        cam=cam,
        stroke=stroke,
        ranges=ranges,
        channels=channels,
        acquisition=model.acquisition.model_dump(exclude_none=True),
        **extra,
        **{k: float(v) for k, v in values.items()},
    )


def load_breaker(path: str | Path) -> Breaker:
    """Load a breaker file; see docs/breaker-file.md for the format."""
    path = Path(path)
    if not path.is_file():
        raise BreakerFileError(f"breaker file not found: {path}")
    try:
        text = path.read_text()
    except UnicodeDecodeError as exc:
        raise BreakerFileError(f"breaker file {path} is not valid TOML: {exc}") from None
    model = parse_breaker_text(text, source=str(path))
    cam = load_cam_profile(path.parent / model.cam.profile) if model.cam is not None else None
    return _build(model, cam, default_name=path.stem, source=path.name, folder=path.parent)


def effect_strengths(text: str, *, source: str = "(text)") -> dict:
    """{effect: typical strength} of a breaker file's text: its ``[effects]`` over the reference
    breaker's (service.mechanics.effects.REFERENCE_STRENGTHS)."""
    model = parse_breaker_text(text, source=source)
    given = {k: v for k, v in model.effects.model_dump().items() if v is not None}
    return {**REFERENCE_STRENGTHS, **given}


def load_effect_strengths(path: str | Path) -> dict:
    """``effect_strengths`` of a breaker file on disk."""
    path = Path(path)
    if not path.is_file():
        raise BreakerFileError(f"breaker file not found: {path}")
    return effect_strengths(path.read_text(), source=str(path))


def cam_profile_from_text(text: str, *, source: str) -> CamProfile:
    """A cam table CSV's text (columns ``camshaft_rad,output_shaft_rad``) as a profile."""
    import io

    if len(text.encode("utf-8", "replace")) > MAX_CAM_BYTES:
        raise BreakerFileError(f"cam profile {source} is larger than {MAX_CAM_BYTES} bytes")
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # numpy warns on no rows: refused below, in words
            table = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise BreakerFileError(f"cam profile {source} is not a two-column numeric CSV: {exc}") from None
    if table.size == 0:
        raise BreakerFileError(f"cam profile {source} holds no data rows (a header line, then "
                               "camshaft_rad,output_shaft_rad rows)")
    if table.shape[1] != 2:
        raise BreakerFileError(f"cam profile {source} must have exactly two columns")
    if not np.isfinite(table).all():
        raise BreakerFileError(f"cam profile {source} holds a NaN or infinite value")
    try:
        return CamProfile.from_table(table[:, 0], table[:, 1])
    except CamProfileError as exc:
        raise BreakerFileError(f"cam profile {source}: {exc}") from None


def load_cam_profile(path: str | Path) -> CamProfile:
    """Read a cam table CSV with columns ``camshaft_rad,output_shaft_rad``."""
    path = Path(path)
    if not path.is_file():
        raise BreakerFileError(f"cam profile not found: {path}")
    return cam_profile_from_text(path.read_text(), source=str(path))
