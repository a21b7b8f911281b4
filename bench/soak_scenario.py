"""The soak's scenario: what each breaker's DAQ delivers, and which alarms are right.

Breaker 1 leaks buffer oil (DO falling), breaker 2's opening spring relaxes (BO falling), the
others are controls. Every breaker sees the same seasonal temperature when the profile is on:
the run's operations span one year, −25…+40 °C with daily swings, and the parameters follow it
(DO −0.4 %/K and BO −0.03 %/K about 20 °C: buffer-oil viscosity and mechanism friction, the
magnitudes issue 21 states). Among the operations the DAQs deliver decoys (a shock with no
motion, a burst of interference). ``bench/soak.py`` is the driver that runs it.
"""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "config" / "breakers" / "reference-252kV.toml"
FS = 128_000.0
DRIFTS = ({"role": "oil leak", "parameter": "DO", "direction": "falling"},
          {"role": "spring relaxation", "parameter": "BO", "direction": "falling"})
TOTAL_DRIFT = 0.15        # relative change of the drifting parameter by the end of the run [-]
DRIFT_FROM = 0.6          # the drift starts after this fraction of a breaker's operations
JITTER = 0.004            # operation-to-operation spread of every parameter [-]
CLOSE_EVERY = 4           # a closing after every 4th opening
DECOY_EVERY = 97          # one DAQ capture in ~97 is a decoy (shock or interference, no motion)
FAULT_EVERY = 151         # one capture download in ~151 gets an exception response
LATE_EVERY = 1999         # one in ~1999 gets a reply later than the driver's timeout


T_REF_C = 20.0            # temperature at which the design parameters hold [°C]
SENSITIVITY_PER_K = {"DO": -0.004, "BO": -0.0003}  # relative change per kelvin (issue 21)
SEASON_MEAN_C, SEASON_AMPLITUDE_C, DAILY_AMPLITUDE_C = 7.5, 26.5, 6.0  # −25…+40 °C in all
DAYS_PER_YEAR = 365.0


def temperature_c(fraction_of_year: float) -> float:
    """Ambient temperature [°C] at a point of the year (0 = mid-January, the coldest)."""
    season = -math.cos(2 * math.pi * fraction_of_year)
    day = -math.cos(2 * math.pi * fraction_of_year * DAYS_PER_YEAR)
    return SEASON_MEAN_C + SEASON_AMPLITUDE_C * season + DAILY_AMPLITUDE_C * day


# -- the scripted history ------------------------------------------------------------------------
class BreakerScript:
    """What one breaker's DAQ delivers: openings (with the breaker's drift), closings, decoys."""

    def __init__(self, breaker, index: int, operations: int, seed: int, *, decoy_every: int = DECOY_EVERY,
                 seasons: bool = False):
        self.breaker, self.index = breaker, index
        self.decoy_every, self.seasons = decoy_every, seasons
        self.drift = DRIFTS[index] if index < len(DRIFTS) else None
        self.operations = operations
        self.rng = np.random.default_rng(seed)
        openings = int(np.ceil(operations * CLOSE_EVERY / (CLOSE_EVERY + 1)))
        self.drift_start = int(openings * DRIFT_FROM)
        self.drift_per_opening = TOTAL_DRIFT / max(1, openings - self.drift_start)
        self._closings = None

    def temperature(self, done: int) -> float | None:
        """Ambient temperature [°C] at real operation ``done`` (None: the profile is off).
        The run's operations are spread evenly over one year, at an odd time of day each."""
        if not self.seasons:
            return None
        return temperature_c((done + 0.37 * self.index) / max(self.operations, 1))

    def parameters(self, opening: int, temperature: float | None = None) -> dict:
        p = dict(self.breaker.design_parameters())
        for k in p:
            p[k] *= 1.0 + self.rng.normal(0.0, JITTER)
        if temperature is not None:
            for k, s in SENSITIVITY_PER_K.items():
                p[k] *= 1.0 + s * (temperature - T_REF_C)
        if self.drift and opening >= self.drift_start:
            sign = -1.0 if self.drift["direction"] == "falling" else 1.0
            p[self.drift["parameter"]] *= 1.0 + sign * self.drift_per_opening * (opening - self.drift_start + 1)
        return p

    def closing_pool(self):
        """Closings do not drift here; 24 of them are synthesised once (a closing costs 0.25 s)."""
        from drivers.synthetic import synthesize_capture

        if self._closings is None:
            self._closings = [synthesize_capture(self.breaker, "close", self.parameters(0), rng=self.rng)[0]
                              for _ in range(24)]
        return self._closings

    def items(self):
        """``(kind, travel, vibration, temperature_c)``: kind "open" | "close" | "decoy";
        ``operations`` real ones. temperature_c is None when the profile is off."""
        from drivers.synthetic import synthesize_capture

        opening = done = n = 0
        while done < self.operations:
            n += 1
            temp = self.temperature(done)
            if n % self.decoy_every == 0:
                yield ("decoy",) + self.decoy(n) + (temp,)
                continue
            if done % (CLOSE_EVERY + 1) == CLOSE_EVERY:
                cap = self.closing_pool()[int(self.rng.integers(24))]
                yield "close", cap.travel, cap.vibration, temp
            else:
                cap, _ = synthesize_capture(self.breaker, "open", self.parameters(opening, temp), rng=self.rng)
                opening += 1
                yield "open", cap.travel, cap.vibration, temp
            done += 1

    def decoy(self, n: int):
        """A capture the DAQ took with no motion: a lone shock, or a burst of interference."""
        samples = 12_000
        rest = 0.0 if n % 2 else float(self.breaker.stroke)
        travel = rest + self.rng.normal(0.0, 0.0015, samples)
        vib = self.rng.normal(0.0, 0.6, samples)
        t = np.arange(samples) / FS
        if (n // self.decoy_every) % 2:
            k = samples // 3
            vib[k:] += 350.0 * np.exp(-(t[k:] - t[k]) / 0.6e-3) * np.sin(2 * np.pi * 2500.0 * (t[k:] - t[k]))
        else:
            a, b = samples // 4, samples // 4 + int(0.05 * FS)
            vib[a:b] += self.rng.normal(0.0, 60.0, b - a)
            travel[a:b] += self.rng.normal(0.0, 0.004, b - a)
        return travel, vib


def breaker_files(tmp: Path, n: int) -> list[Path]:
    text = REFERENCE.read_text()
    cam = REFERENCE.parent / "reference-252kV.cam.csv"
    out = []
    for i in range(n):
        role = DRIFTS[i]["role"].replace(" ", "-") if i < len(DRIFTS) else "control"
        name = f"soak{i + 1}-{role}"
        p = tmp / f"{name}.toml"
        p.write_text(re.sub(r'(?m)^name = ".*"$', f'name = "{name}"', text, count=1))
        shutil.copy(cam, tmp / cam.name)
        out.append(p)
    return out




def judge_alarms(scripts, alarms, names: dict) -> dict:
    """Which raised alarms were scripted. ``alarms``: (breaker_id, parameter, level, state,
    evidence, operation_id) rows; ``names``: breaker id -> name. Any raised state that is not the
    scripted drift of its breaker, in its direction, is false: on a control, or the wrong way."""
    drifted = {s.breaker.name for s in scripts if s.drift}
    raised: dict[str, list] = {n: [] for n in names.values()}
    scripted_drift = {s.breaker.name: (s.drift["parameter"], s.drift["direction"]) for s in scripts if s.drift}
    false = []
    for breaker_id, parameter, level, st, evidence, op_id in alarms:
        name = names[breaker_id]
        direction = (evidence or {}).get("drift_direction")
        text = f"{parameter} {direction} {level} ({st}) at operation {op_id}"
        raised[name].append(text)
        if scripted_drift.get(name) != (parameter, direction):
            false.append({"breaker": name, "alarm": text, "level": level})
    expected_ok = all(any(a.startswith(f"{p} {d} alarm") for a in raised[n]) for n, (p, d) in scripted_drift.items())
    return {
        "alarms_expected": len(drifted), "alarms_raised": sum(len(v) for v in raised.values()),
        "alarms_by_breaker": raised, "every_drift_alarmed": expected_ok,
        "control_breakers_alarmed": sum(1 for n, v in raised.items() if n not in drifted and v),
        "control_breakers_alarm_level": sum(1 for n, v in raised.items()
                                            if n not in drifted and any(" alarm (" in a for a in v)),
        "false_alarms": false,
        "false_warnings": len(false),  # every false raise starts as a warning: all of them count
    }
