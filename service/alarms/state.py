"""The detector's persisted state of one watched parameter of one breaker (``DriftState``) and
the summary of its learnt baseline (``Baseline``). Pure; ``drift.update`` moves it on."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from datetime import datetime
from typing import Any, Mapping

from service.alarms.baseline import Model
from service.alarms.observation import utc_text
from service.alarms.settings import DriftSettings

LEVELS = ("none", "warning", "alarm")
STATE_VERSION = 2


@dataclass(frozen=True)
class Baseline:
    """Summary of a breaker's learnt baseline of one parameter (for evidence and the page).

    mean, sd : expected value (at the window's mean temperature) and run-to-run sd [unit]
    n : fits in the window; operation_ids: the window's fits; excluded_ids: screened out
    slope : temperature slope [unit/K] (0 without compensation); t_mean, t_span [C, K]
    compensated : the model uses temperature; frozen : the window has stopped learning
    """

    mean: float
    sd: float
    n: int
    operation_ids: tuple
    excluded_ids: tuple = ()
    slope: float = 0.0
    slope_sd: float = 0.0
    t_mean: float | None = None
    t_span: float = 0.0
    compensated: bool = False
    frozen: bool = False

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["operation_ids"] = list(self.operation_ids)
        out["excluded_operation_ids"] = list(out.pop("excluded_ids"))
        return out


@dataclass(frozen=True)
class DriftState:
    """Detector state of one watched parameter of one breaker; persist it with ``to_dict``.

    phase : "baseline" while the first ``baseline_n`` good fits are collected, then "monitoring"
    collected : ((operation_id, value, temperature, se), ...) while in the baseline phase
    window : the baseline's fits, same tuples (values winsorised); model : its predictive model
    frozen : the window has stopped learning
    s_rising, s_falling : the two one-sided CUSUMs [z]
    run_rising, run_falling : operation ids since each CUSUM last left zero (newest last)
    level : "none" | "warning" | "alarm"; episode: number of the current or last alarm
    """

    parameter: str
    phase: str = "baseline"
    collected: tuple = ()
    window: tuple = ()
    excluded_ids: tuple = ()
    model: Model | None = None
    frozen: bool = False
    s_rising: float = 0.0
    s_falling: float = 0.0
    run_rising: tuple = ()
    run_falling: tuple = ()
    run_length_rising: int = 0
    run_length_falling: int = 0
    level: str = "none"
    acknowledged: bool = False
    acknowledged_by: str | None = None
    acknowledged_at: datetime | None = None
    below_count: int = 0
    episode: int = 0
    last_operation_id: int | str | None = None
    last_time: datetime | None = None
    last_z: float | None = None
    last_score: float | None = None
    last_expected: float | None = None
    last_band: float | None = None
    held: tuple | None = None  # (operation_id, score): an unsupported extreme fit, on hold
    outliers_ignored: int = 0
    fits_monitored: int = 0

    @classmethod
    def new(cls, parameter: str, settings: DriftSettings) -> "DriftState":
        """Fresh state: the next ``settings.baseline_n`` good fits form the baseline."""
        settings.direction(parameter)  # refuse unwatched parameters early
        return cls(parameter=parameter)

    @property
    def statistic(self) -> float:
        """The larger of the two CUSUMs [z] (only the watched sides ever leave zero)."""
        return max(self.s_rising, self.s_falling)

    @property
    def active(self) -> bool:
        return self.level != "none"

    @property
    def compensated(self) -> bool:
        """The baseline model uses the temperature."""
        return self.model is not None and self.model.compensated

    @property
    def baseline(self) -> Baseline | None:
        m = self.model
        if m is None:
            return None
        return Baseline(mean=m.centre, sd=m.sd, n=m.n, operation_ids=tuple(w[0] for w in self.window),
                        excluded_ids=self.excluded_ids, slope=m.slope, slope_sd=math.sqrt(m.slope_var),
                        t_mean=m.t_mean, t_span=m.t_span, compensated=m.compensated, frozen=self.frozen)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (no NaN); ``DriftState.from_dict`` is its inverse."""
        out = {f: getattr(self, f) for f in self.__dataclass_fields__}
        out["version"] = STATE_VERSION
        for key in ("collected", "window"):
            out[key] = [list(c) for c in out[key]]
        out["excluded_ids"] = list(self.excluded_ids)
        out["model"] = self.model.to_dict() if self.model else None
        # The summary, for readers of the stored state (retention keeps these operations' captures).
        out["baseline"] = self.baseline.to_dict() if self.model else None
        out["run_rising"] = list(self.run_rising)
        out["run_falling"] = list(self.run_falling)
        out["held"] = list(self.held) if self.held is not None else None
        for key in ("acknowledged_at", "last_time"):
            out[key] = utc_text(out[key]) if out[key] else None
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "DriftState":
        if data.get("version") == 1:
            data = _from_version_1(data)
        if data.get("version") != STATE_VERSION:
            raise ValueError(f"drift state version {data.get('version')!r} is not supported "
                             f"(expected {STATE_VERSION}); reset the baseline or replay the history")
        d = {k: v for k, v in data.items() if k not in ("version", "baseline")}
        for key in ("collected", "window"):
            d[key] = tuple(tuple(c) for c in d.get(key, ()))
        d["excluded_ids"] = tuple(d.get("excluded_ids", ()))
        d["model"] = Model.from_dict(d["model"]) if d.get("model") else None
        d["run_rising"] = tuple(d.get("run_rising", ()))
        d["run_falling"] = tuple(d.get("run_falling", ()))
        d["held"] = tuple(d["held"]) if d.get("held") is not None else None
        for key in ("acknowledged_at", "last_time"):
            if d.get(key):
                d[key] = datetime.fromisoformat(d[key])
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"unknown drift state fields: {', '.join(sorted(unknown))}")
        return cls(**d)


def _from_version_1(data: Mapping[str, Any]) -> dict[str, Any]:
    """A state of the frozen-20-fit detector (version 1) as a version-2 state: its baseline
    stays frozen (v1 kept only mean, sd and n, not the fits to learn from) and its CUSUM, level
    and episode carry on, so stored alarms stay in step. A baseline reset starts the learning
    baseline."""
    d = {k: v for k, v in data.items() if k not in ("baseline", "version")}
    b = data.get("baseline")
    d["version"] = STATE_VERSION
    d["collected"] = [[c[0], c[1], None, 0.0] for c in data.get("collected", ())]
    if b is not None:
        d["model"] = Model(n=int(b["n"]), dof=max(int(b["n"]) - 1, 1), centre=float(b["mean"]),
                           slope=0.0, slope_var=0.0, sd=float(b["sd"]), se2_mean=0.0).to_dict()
        d["window"] = [[i, float(b["mean"]), None, 0.0] for i in b.get("operation_ids", ())]
        d["excluded_ids"] = list(b.get("excluded_operation_ids", ()))
        d["frozen"] = True
    return d
