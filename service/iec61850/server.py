"""The IEC 61850 (MMS) server: libiec61850 through pyiec61850-ng, fed from the database.

Builds a dynamic libiec61850 model from ``points.logical_device`` for every breaker, serves it
on ``settings.iec61850_port``, and polls the database (``snapshot``) so values, qualities and
time stamps follow the stored fits and alarms; changes of the alarm dataset go out by report.
A breaker registered or re-tagged while running rebuilds the model (clients reconnect).
"""

from __future__ import annotations

import logging
import threading
import time
from datetime import datetime, timezone

from service.errors import UserError, in_words

from . import points as pm
from .snapshot import OperatingTimeCache, breaker_views, breakers, fingerprint

log = logging.getLogger("hvcb.iec61850")

POLL_S = 0.5          # database poll interval [s]
FULL_REFRESH_S = 5.0  # full re-read even without a change: DAQ-down and staleness [s]


class Iec61850Error(UserError):
    """The server cannot run (library missing, port taken); the message says why."""


def preflight(port: int) -> None:
    """Refuse to start, in words, when the library is missing or the port cannot be bound
    (``hvcb serve`` calls this before uvicorn, whose start-up errors come as tracebacks)."""
    import socket

    _library()
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("0.0.0.0", port))
        except OSError as exc:
            raise Iec61850Error(f"the IEC 61850 server cannot listen on port {port} ({exc.strerror}); "
                                f"set iec61850_port (HVCB_IEC61850_PORT) to a free port") from None


def _library():
    try:
        import pyiec61850.pyiec61850 as lib
    except ImportError as exc:
        raise Iec61850Error("iec61850_port is set but the IEC 61850 library is not installed: "
                            "pip install 'hvcb[iec61850]' (pyiec61850-ng)") from exc
    return lib


def _software_revision() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("hvcb")
    except PackageNotFoundError:
        return "dev"


def _ms(t: datetime) -> int:
    return int(t.astimezone(timezone.utc).timestamp() * 1000)


class _Model:
    """One libiec61850 model + server for a set of logical devices."""

    def __init__(self, lib, lds: list[pm.LogicalDevice]):
        self.lib, self.lds = lib, lds
        L = lib
        mn = L.toModelNode
        self.model = L.IedModel_create(pm.IED_NAME)
        self.cdc = {}
        strings = []  # (DataAttribute, text) set before the server starts
        for ld in lds:
            dev = L.LogicalDevice_create(ld.inst, self.model)
            nodes = {name: L.LogicalNode_create(name, dev) for name in ld.logical_nodes}
            for o in ld.objects:
                parent = mn(nodes[o.ln])
                if o.cdc == "SPS":
                    do = L.CDC_SPS_create(o.name, parent, 0)
                elif o.cdc == "INS":
                    do = L.CDC_INS_create(o.name, parent, 0)
                elif o.cdc == "ENS":
                    do = L.CDC_ENS_create(o.name, parent, 0)
                elif o.cdc == "MV":
                    do = L.CDC_MV_create(o.name, parent, 0, False)
                elif o.cdc == "DPC":
                    do = L.CDC_DPC_create(o.name, parent, 0, L.CDC_CTL_MODEL_NONE)
                elif o.cdc == "LPL":
                    do = L.CDC_LPL_create(o.name, parent, L.CDC_OPTION_DESC | L.CDC_OPTION_AC_LN0_M
                                          | L.CDC_OPTION_AC_LN0_EX)
                elif o.cdc == "DPL":
                    do = L.CDC_DPL_create(o.name, parent, 0)
                else:  # pragma: no cover - points.CDC_ATTRIBUTES lists what exists
                    raise ValueError(f"no builder for CDC {o.cdc}")
                self.cdc[f"{ld.name}/{o.ln}.{o.name}"] = o.cdc
                if o.namespace:
                    ns = L.DataAttribute_create("dataNs", mn(do), L.IEC61850_VISIBLE_STRING_255,
                                                L.IEC61850_FC_EX, 0, 0, 0)
                    d = L.DataAttribute_create("d", mn(do), L.IEC61850_VISIBLE_STRING_255,
                                               L.IEC61850_FC_DC, 0, 0, 0)
                    strings += [(ns, o.namespace), (d, pm.description(o))]
            ds = L.DataSet_create(pm.DATASET, nodes["LLN0"])
            for member in ld.dataset:
                ln, do_name = member.split(".")
                L.DataSetEntry_create(ds, f"{ln}$ST${do_name}", -1, None)
            L.ReportControlBlock_create(
                pm.RCB, nodes["LLN0"], f"{ld.name}{pm.DATASET}", False, pm.DATASET, 1,
                L.TRG_OPT_DATA_CHANGED | L.TRG_OPT_QUALITY_CHANGED | L.TRG_OPT_GI,
                L.RPT_OPT_SEQ_NUM | L.RPT_OPT_TIME_STAMP | L.RPT_OPT_REASON_FOR_INCLUSION
                | L.RPT_OPT_DATA_SET | L.RPT_OPT_DATA_REFERENCE, 50, 0)
        rev = _software_revision()
        for ld in lds:
            strings += [(self._da(f"{ld.name}/LLN0.NamPlt.vendor"), "hvcb"),
                        (self._da(f"{ld.name}/LLN0.NamPlt.swRev"), rev),
                        (self._da(f"{ld.name}/LLN0.NamPlt.d"), f"breaker {ld.breaker}"),
                        (self._da(f"{ld.name}/LLN0.NamPlt.configRev"), "1"),
                        (self._da(f"{ld.name}/LLN0.NamPlt.ldNs"), pm.STANDARD_NS),
                        (self._da(f"{ld.name}/LPHD1.PhyNam.vendor"), "hvcb")]
        for da, text in strings:
            v = L.MmsValue_newVisibleString(text)
            L.DataAttribute_setValue(da, v)
            L.MmsValue_delete(v)
        self.server = None
        self.last: dict[str, tuple] = {}

    def _da(self, ref: str):
        node = self.lib.IedModel_getModelNodeByObjectReference(self.model, ref)
        if not node:
            raise KeyError(f"model has no {ref}")
        return self.lib.toDataAttribute(node)

    def start(self, port: int) -> None:
        L = self.lib
        self.server = L.IedServer_create(self.model)
        L.IedServer_start(self.server, port)
        if not L.IedServer_isRunning(self.server):
            self.close()
            raise Iec61850Error(f"the IEC 61850 server cannot listen on port {port} "
                                f"(in use, or below 1024 without privileges)")

    def close(self) -> None:
        L = self.lib
        if self.server is not None:
            L.IedServer_stop(self.server)
            L.IedServer_destroy(self.server)
            self.server = None
        if self.model is not None:
            L.IedModel_destroy(self.model)
            self.model = None

    def _quality(self, q: str) -> int:
        L = self.lib
        return {pm.GOOD: L.QUALITY_VALIDITY_GOOD, pm.INVALID: L.QUALITY_VALIDITY_INVALID,
                pm.OLD: L.QUALITY_VALIDITY_QUESTIONABLE | L.QUALITY_DETAIL_OLD_DATA,
                pm.INACCURATE: L.QUALITY_VALIDITY_QUESTIONABLE | L.QUALITY_DETAIL_INACCURATE}[q]

    def apply(self, ld: pm.LogicalDevice, vals: dict[str, pm.Value]) -> int:
        """Write changed values; returns how many data objects changed."""
        L, srv = self.lib, self.server
        changed = 0
        L.IedServer_lockDataModel(srv)
        try:
            for key, v in vals.items():
                ref = f"{ld.name}/{key}"
                cdc = self.cdc[ref]
                fc_t = v.t if cdc in ("MV", "INS", "DPC") else None  # event time vs "now"
                state = (v.value, v.quality, fc_t)
                if self.last.get(ref) == state:
                    continue
                self.last[ref] = state
                changed += 1
                if v.t is not None:
                    L.IedServer_updateUTCTimeAttributeValue(srv, self._da(ref + ".t"), _ms(v.t))
                if cdc == "MV":
                    if v.value is not None:
                        L.IedServer_updateFloatAttributeValue(srv, self._da(ref + ".mag.f"), float(v.value))
                elif cdc == "SPS":
                    L.IedServer_updateBooleanAttributeValue(srv, self._da(ref + ".stVal"), bool(v.value))
                elif cdc in ("INS", "ENS"):
                    L.IedServer_updateInt32AttributeValue(srv, self._da(ref + ".stVal"), int(v.value))
                elif cdc == "DPC":
                    pos = {pm.POS_OFF: L.DBPOS_OFF, pm.POS_ON: L.DBPOS_ON,
                           pm.POS_INTERMEDIATE: L.DBPOS_INTERMEDIATE_STATE}[v.value]
                    L.IedServer_updateDbposValue(srv, self._da(ref + ".stVal"), pos)
                L.IedServer_updateQuality(srv, self._da(ref + ".q"), self._quality(v.quality))
        finally:
            L.IedServer_unlockDataModel(srv)
        return changed


class Iec61850Server:
    """Runs in the service process: ``start()`` serves, a thread keeps the values current."""

    def __init__(self, settings, Session, *, poll_s: float = POLL_S):
        self.settings, self.Session, self.poll_s = settings, Session, poll_s
        self.port = int(settings.iec61850_port)
        self.lib = _library()
        self._model: _Model | None = None
        self._lds: dict[int, pm.LogicalDevice] = {}
        self._cache = OperatingTimeCache()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._fingerprint = None
        self._last_full = 0.0

    # -- lifecycle -----------------------------------------------------------------------------
    def start(self) -> None:
        with self.Session() as session:
            self._build(breakers(session))
        self._refresh(force=True)
        self._thread = threading.Thread(target=self._run, name="hvcb-iec61850", daemon=True)
        self._thread.start()
        log.info("IEC 61850 server on port %d: %s", self.port,
                 ", ".join(ld.name for ld in self._lds.values()) or "no breakers")

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
            self._thread = None
        if self._model is not None:
            self._model.close()
            self._model = None

    @property
    def logical_devices(self) -> list[pm.LogicalDevice]:
        return list(self._lds.values())

    def _build(self, rows: list[tuple[int, str, str]]) -> None:
        watched = list(self.settings.drift_settings.watched)
        lds = {}
        for bid, name, tag in rows:
            problem = pm.ld_inst_problem(tag)
            if problem:
                log.warning("IEC 61850: breaker %s left out: %s", name, problem)
                continue
            lds[bid] = pm.logical_device(tag, name, watched)
        if self._model is not None:
            self._model.close()
            self._model = None
        model = _Model(self.lib, list(lds.values()))
        model.start(self.port)
        self._model, self._lds = model, lds
        self._rows = rows

    # -- polling -------------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.wait(self.poll_s):
            try:
                self._refresh()
            except Exception as exc:  # the DB may be down for a while; keep serving the last values
                log.warning("IEC 61850: refresh failed (%s); last values kept", in_words(exc))

    def _refresh(self, force: bool = False) -> None:
        now_m = time.monotonic()
        with self.Session() as session:
            fp = fingerprint(session)
            if not force and fp == self._fingerprint and now_m - self._last_full < FULL_REFRESH_S:
                return
            rows = breakers(session)
            if rows != self._rows:
                log.info("IEC 61850: breakers changed; rebuilding the model")
                self._build(rows)
            now = datetime.now(timezone.utc)
            views = breaker_views(session, now=now, daq_timeout_s=self.settings.daq_timeout_s,
                                  drift_settings=self.settings.drift_settings, cache=self._cache)
        for bid, ld in self._lds.items():
            if bid in views:
                vals = pm.values(ld, views[bid], now=now, stale_after_s=self.settings.stale_after_s)
                self._model.apply(ld, vals)
        self._fingerprint, self._last_full = fp, now_m
