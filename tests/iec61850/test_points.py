"""The point map on its own: names, namespaces and values from a breaker view (no server)."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from service.alarms.settings import DriftSettings
from service.iec61850 import points as pm

NOW = datetime(2026, 11, 23, 9, 0, tzinfo=timezone.utc)
POINT_MAP_PAGE = Path(__file__).resolve().parents[2] / "docs" / "iec61850.md"


def ld():
    return pm.logical_device("Q1", "reference-252kV", ["DO", "BO"])


def test_reference_breaker_is_hvcbQ1_with_standard_nodes_and_counter():
    dev = ld()
    assert dev.name == "hvcbQ1"
    assert dev.logical_nodes == ["LLN0", "LPHD1", "XCBR1", "SCBR1", "SOPM1"]
    refs = {p.reference: p for p in pm.points(dev)}
    assert refs["hvcbQ1/XCBR1.OpCnt.stVal"].type == "INT32"
    assert refs["hvcbQ1/XCBR1.OpCnt.stVal"].namespace == "IEC 61850-7-4"
    for name in ("OpTmOpn", "OpTmCls"):
        assert refs[f"hvcbQ1/SCBR1.{name}.mag.f"].fc == "MX"
    for name in ("OpTmWrn", "OpTmAlm"):
        assert refs[f"hvcbQ1/SCBR1.{name}.stVal"].type == "BOOLEAN"


def test_fitted_parameters_and_drift_alarms_are_declared_hvcb_extensions():
    dev = ld()
    ext = [o for o in dev.objects if o.namespace]
    assert {o.name for o in ext} == {"AO", "BO", "DO", "EO", "AC", "BC", "CC", "DOWrn", "DOAlm", "BOWrn", "BOAlm",
                                   "OpsToLim", "LatTm"}
    assert all(o.ln == "SOPM1" and o.namespace == pm.HVCB_NS for o in ext)
    refs = {p.reference: p for p in pm.points(dev)}
    for o in ext:
        assert refs[f"hvcbQ1/SOPM1.{o.name}.dataNs"].fc == "EX"
    std = [o for o in dev.objects if not o.namespace]
    assert not any(f"hvcbQ1/{o.ln}.{o.name}.dataNs" in refs for o in std)
    assert {"SOPM1.DOWrn", "SOPM1.DOAlm", "SOPM1.BOWrn", "SOPM1.BOAlm"} <= set(dev.dataset)


@pytest.mark.parametrize("tag", ["reference-252kV", "1Q", "", "Q" * 70])
def test_tag_that_cannot_be_a_logical_device_is_refused_in_words(tag):
    assert pm.ld_inst_problem(tag)
    with pytest.raises(ValueError, match="logical-device"):
        pm.logical_device(tag, "b", ["DO"])


def _view(**kw):
    fit_o = pm.FitView(parameters={"AO": 3424.0, "BO": 4806.0, "DO": 39.5, "EO": 3950.0}, identifiable=True,
                       occurred_at=NOW - timedelta(hours=1), operating_time_s=0.021)
    fit_c = pm.FitView(parameters={"AC": 23600.0, "BC": 2.56, "CC": 10400.0}, identifiable=False,
                       occurred_at=NOW - timedelta(minutes=30), operating_time_s=0.036)
    base = dict(name="b", tag="Q1", operations=7, last_kind="close", last_operation_at=NOW - timedelta(minutes=30),
                fits={"open": fit_o, "close": fit_c}, alarms={"DO": "warning"})
    base.update(kw)
    return pm.BreakerView(**base)


def test_values_follow_fits_alarms_and_quality():
    v = pm.values(ld(), _view(), now=NOW, stale_after_s=86400)
    assert v["XCBR1.OpCnt"].value == 7 and v["XCBR1.Pos"].value == pm.POS_ON
    assert v["SOPM1.DO"].value == 39.5 and v["SOPM1.DO"].quality == pm.GOOD
    assert v["SOPM1.DO"].t == NOW - timedelta(hours=1)
    assert v["SOPM1.AC"].quality == pm.INACCURATE  # closing fit not identifiable
    assert v["SCBR1.OpTmOpn"].value == pytest.approx(0.021)
    assert v["SOPM1.DOWrn"].value is True and v["SOPM1.DOAlm"].value is False
    assert v["SOPM1.BOWrn"].value is False
    assert v["SOPM1.Health"].value == 2 and v["LLN0.Health"].value == 2
    assert v["SCBR1.OpTmAlm"].value is False and v["SCBR1.Health"].value == 1
    stale = pm.values(ld(), _view(daq_down=True), now=NOW, stale_after_s=86400)
    assert stale["SOPM1.DO"].quality == pm.OLD and stale["LPHD1.PhyHealth"].value == 2
    empty = pm.values(ld(), pm.BreakerView(name="b", tag="Q1"), now=NOW, stale_after_s=86400)
    assert empty["SOPM1.AO"].quality == pm.INVALID and empty["XCBR1.Pos"].quality == pm.INVALID
    assert empty["XCBR1.OpCnt"].value == 0
    assert empty["SOPM1.OpsToLim"].quality == pm.INVALID  # no limits
    soon = pm.values(ld(), _view(soonest=("DO", 42.0, NOW)), now=NOW, stale_after_s=86400)["SOPM1.OpsToLim"]
    assert (soon.value, soon.quality, soon.t) == (42.0, pm.GOOD, NOW)
    never = pm.values(ld(), _view(soonest=("DO", None, NOW)), now=NOW, stale_after_s=86400)["SOPM1.OpsToLim"]
    assert never.value is None and never.quality == pm.INVALID  # no crossing within the horizon
    every = {f"{o.ln}.{o.name}" for o in ld().objects if o.cdc not in ("LPL", "DPL")}
    assert set(v) == every


def test_operating_time_drift_uses_the_project_detector():
    settings = DriftSettings(baseline_n=10)
    t0 = NOW - timedelta(days=1)
    steady = [(i, t0 + timedelta(minutes=i), 0.021 * (1 + 0.002 * ((-1) ** i))) for i in range(30)]
    assert pm.operating_time_level(steady, settings) == "none"
    slowing = steady[:12] + [(i, t0 + timedelta(minutes=i), 0.021 * 1.03 ** (i - 11)) for i in range(12, 30)]
    assert pm.operating_time_level(slowing, settings) == "alarm"


def test_docs_list_the_point_map():
    assert pm.markdown_table(ld()) in POINT_MAP_PAGE.read_text()
