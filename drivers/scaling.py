"""Channel scaling: the DAQ's int16 codes to our physical units and back.

Travel: a 0–180° resistive sensor on a 16-bit converter. Code −32768 is the closed position
(travel 0 rad) and code +32767 is the sensor's full scale (π rad unless configured), so one LSB
is ``full_scale / 65535`` — the same quantum ``synthesize_capture`` uses, so synthetic travel
round-trips exactly.

Vibration: a ±1000 g accelerometer, symmetric on ±32767; it clips at full scale (−32768 reads as
−full scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CODE_MIN = -32768
CODE_MAX = 32767
CODE_SPAN = CODE_MAX - CODE_MIN  # 65535 steps over the travel sensor's range


@dataclass(frozen=True)
class ChannelScaling:
    """int16 code ↔ physical units for the two channels.

    Attributes
    ----------
    sample_rate_hz : float
        DAQ sample rate [Hz].
    travel_full_scale_rad : float
        Travel at code +32767 [rad from closed]; code −32768 is ``travel_zero_rad``.
    travel_zero_rad : float
        Travel at code −32768 [rad from closed] (sensor mounting offset).
    vibration_full_scale_g : float
        Acceleration at code ±32767 [g].
    """

    sample_rate_hz: float = 128_000.0
    travel_full_scale_rad: float = math.pi
    travel_zero_rad: float = 0.0
    vibration_full_scale_g: float = 1000.0

    def __post_init__(self):
        if not (self.sample_rate_hz > 0 and math.isfinite(self.sample_rate_hz)):
            raise ValueError(f"sample rate must be a positive number of Hz, got {self.sample_rate_hz}")
        if not self.travel_full_scale_rad > self.travel_zero_rad:
            raise ValueError("travel full scale must exceed the travel at code -32768 "
                             f"({self.travel_full_scale_rad} <= {self.travel_zero_rad} rad)")
        if not self.vibration_full_scale_g > 0:
            raise ValueError(f"vibration full scale must be positive, got {self.vibration_full_scale_g} g")

    @classmethod
    def from_breaker(cls, breaker) -> "ChannelScaling":
        """Scaling from ``breaker.acquisition`` (keys ``sample_rate_hz``, ``travel_full_scale_rad``,
        ``vibration_full_scale_g``); missing keys take the defaults."""
        acq = dict(getattr(breaker, "acquisition", None) or {})
        return cls(sample_rate_hz=float(acq.get("sample_rate_hz", cls.sample_rate_hz)),
                   travel_full_scale_rad=float(acq.get("travel_full_scale_rad", cls.travel_full_scale_rad)),
                   travel_zero_rad=float(acq.get("travel_zero_rad", cls.travel_zero_rad)),
                   vibration_full_scale_g=float(acq.get("vibration_full_scale_g", cls.vibration_full_scale_g)))

    @property
    def travel_lsb_rad(self) -> float:
        """One travel code step [rad]."""
        return (self.travel_full_scale_rad - self.travel_zero_rad) / CODE_SPAN

    @property
    def vibration_lsb_g(self) -> float:
        """One vibration code step [g]."""
        return self.vibration_full_scale_g / CODE_MAX

    @property
    def travel_limits(self) -> tuple[float, float]:
        """Representable travel [rad]."""
        return (self.travel_zero_rad, self.travel_full_scale_rad)

    @property
    def vibration_limits(self) -> tuple[float, float]:
        """Representable acceleration [g]."""
        return (-self.vibration_full_scale_g, self.vibration_full_scale_g)

    def travel_to_code(self, travel_rad) -> np.ndarray:
        """Travel [rad] → int16 codes, rounded and clipped to the sensor range."""
        x = (np.asarray(travel_rad, dtype=float) - self.travel_zero_rad) / self.travel_lsb_rad + CODE_MIN
        return np.clip(np.rint(x), CODE_MIN, CODE_MAX).astype(np.int16)

    def code_to_travel(self, codes) -> np.ndarray:
        """int16 codes → travel [rad from closed]."""
        c = np.asarray(codes, dtype=float)
        return self.travel_zero_rad + (c - CODE_MIN) * self.travel_lsb_rad

    def vibration_to_code(self, vibration_g) -> np.ndarray:
        """Acceleration [g] → int16 codes, clipped at ±full scale like the sensor."""
        x = np.asarray(vibration_g, dtype=float) / self.vibration_lsb_g
        return np.clip(np.rint(x), -CODE_MAX, CODE_MAX).astype(np.int16)

    def code_to_vibration(self, codes) -> np.ndarray:
        """int16 codes → acceleration [g]; −32768 reads as −full scale (clipped)."""
        c = np.maximum(np.asarray(codes, dtype=float), -CODE_MAX)
        return c * self.vibration_lsb_g
