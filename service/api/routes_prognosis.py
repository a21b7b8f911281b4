"""GET /api/v1/breakers/{name}/prognosis: operations and date until each limited parameter
crosses its maintenance limit, with 5/50/95 % quantiles (docs/prognosis.md)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path as PathParam
from pydantic import BaseModel, Field

from service.jobs.prognosis import HOW_TO_ADD, as_json, breaker_prognoses

from . import schemas as s
from .deps import ReaderDep, SessionDep, SettingsDep
from .routes_alarms import _breaker_ref

router = APIRouter(prefix="/api/v1", tags=["prognosis"])
BreakerRef = Annotated[str, PathParam(min_length=1, max_length=120, description="breaker name, tag or id")]
ERRORS = {401: {"model": s.Message, "description": "no or unknown API key"},
          403: {"model": s.Message, "description": "the key may not read"},
          404: {"model": s.Message, "description": "no such breaker"}}


class OperationQuantiles(BaseModel):
    p05: float | None = Field(description="5 % quantile of the operations still to go; None beyond the horizon")
    median: float | None = Field(description="median; None with status \"no trend\" (the 5 % quantile, the "
                                              "earliest crossing, still stands)")
    p95: float | None = Field(description="95 % quantile; None beyond the horizon")


class DateQuantiles(BaseModel):
    p05: s.UtcTime | None
    median: s.UtcTime | None
    p95: s.UtcTime | None


class ParameterPrognosis(BaseModel):
    parameter: str = Field(description="fitted parameter, e.g. DO")
    limit: float | None = Field(description="the limit's value [the parameter's unit]")
    limit_text: str = Field(description="the limit as the breaker file writes it")
    direction: str | None = Field(description='"falling" (a lower limit) or "rising" (an upper one)')
    current: float | None = Field(description="the trend's level now, temperature-compensated [unit]")
    baseline: float | None = Field(None, description="the compensated baseline [unit]")
    operations_to_limit: OperationQuantiles | None = Field(
        description="openings still to go until the limit, whole openings; null: no crossing within the horizon")
    date_to_limit: DateQuantiles | None = Field(
        description="the dates, from the breaker's own operation rate; null as above or without a rate")
    model: str
    basis: str | None = Field(description='"change point" (the active alarm\'s) or "baseline reset"')
    basis_operations: int = Field(description="fits the trend was drawn through")
    rate_per_day: float | None = Field(description="fitted openings per day over the last year")
    horizon_years: float | None
    horizon_operations: float | None
    probability_within_horizon: float | None = Field(description="P(crossing before the horizon)")
    reference_temperature_c: float | None = Field(description="values are compensated to this temperature")
    status: str = Field(description='"ok"; "crossed": the trend is past the limit now (service is due); '
                                    'or "no trend" (why in reason)')
    reason: str
    fan: dict = Field(description="projected level (p05, median, p95) over operations from the basis's "
                                  "first fit, and the observed compensated values: the page's fan chart")
    limits: list[dict] = Field([], description="every bound of the limit: {direction, value [unit]} (both sides "
                                               "of a two-sided limit)")
    paths: dict[str, float] = Field({}, description="weight of each candidate degradation path (pseudo-BMA+)")
    seasonal: bool = Field(False, description="the annual cycle was fitted (no temperature, a year of history)")
    low_frequency_sd: float | None = Field(None, description="sd of the annual cycle the interval carries when "
                                                             "under a year without temperature [unit]")
    summary: str = Field("", description="the prognosis in words, with units (the breaker page's card)")


class PrognosisResponse(BaseModel):
    breaker_id: int
    breaker: str
    parameters: list[ParameterPrognosis]
    message: str = Field(description="what to do when the breaker has no limits; empty otherwise")


def _public(p) -> ParameterPrognosis:
    q, d = p.operations_to_limit, p.date_to_limit
    r = (lambda v: None if v is None else round(float(v), 1))  # noqa: E731
    return ParameterPrognosis(
        parameter=p.parameter, limit=p.limit, limit_text=p.limit_text, direction=p.direction,
        current=p.current, baseline=p.baseline,
        operations_to_limit=OperationQuantiles(p05=r(q.p05), median=r(q.median), p95=r(q.p95)) if q else None,
        date_to_limit=DateQuantiles(p05=d.p05, median=d.median, p95=d.p95) if d else None,
        model=p.model, basis=p.basis, basis_operations=p.basis_operations, rate_per_day=p.rate_per_day,
        horizon_years=p.horizon_years, horizon_operations=p.horizon_operations,
        probability_within_horizon=p.probability_within_horizon,
        reference_temperature_c=p.reference_temperature, status=p.status, reason=p.reason, fan=p.fan,
        limits=p.limits, paths=p.paths, seasonal=p.seasonal, low_frequency_sd=p.low_frequency_sd,
        summary=as_json(p)["summary"])


@router.get("/breakers/{name}/prognosis", response_model=PrognosisResponse, responses=ERRORS)
def prognosis(name: BreakerRef, session: SessionDep, settings: SettingsDep, _: ReaderDep) -> PrognosisResponse:
    """When each limited parameter crosses its limit: operations and date, 5/50/95 % quantiles.

    A breaker without a `[limits]` table answers an empty list and says how to add one. Quantiles
    are whole operations. A quantile beyond the horizon (10 years at the breaker's own rate) is
    null: "no crossing within 10 years". When the median lies beyond the horizon, or the status is
    "no trend" (the slope's 90 % interval holds zero), the median is null and the 5 % quantile, the
    earliest crossing, stays when it lies within the horizon.
    """
    b = _breaker_ref(session, name)
    progs = breaker_prognoses(session, breaker=b, settings=settings.drift_settings)
    return PrognosisResponse(breaker_id=b.id, breaker=b.name, parameters=[_public(p) for p in progs],
                             message="" if progs else f"{b.name} has no maintenance limits: {HOW_TO_ADD}")
