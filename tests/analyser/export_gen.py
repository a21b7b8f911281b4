"""Analyser exports made in the test (no large files committed): the CIBANO/TM1800-style layout
of shared/realworld/analyser-csv/, with a model curve of known parameters.

Travel T1 in mm from open (rising on closing), stroke 182 mm = 1 rad of the reference breaker;
the opening follows the reference model (Table 1 design values, α0 = 0.698 rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from service.breaker_file import load_breaker
from service.estimation.curves import ClosingCurves, OpeningCurves

from tests.conftest import BREAKER_FILE

STROKE_MM = 182.0


@dataclass
class Spec:
    rate: float = 10_000.0
    header: bool = True
    crlf: bool = False
    trailing_comma: bool = True
    sequence: str = "CO"            # "CO", "O-CO", "O", "C"
    length_ms: float = 400.0
    t_first_ms: float = 5.0         # first command
    gap_ms: float = 300.0           # command to command (t_co / the O-CO dead time)
    coil_to_motion_open_ms: float = 15.0
    coil_to_motion_close_ms: float = 40.0
    wired_travel: tuple = (1,)
    noise_mm: float = 0.12
    seed: int = 1
    stated_rate: float | None = None  # header rate if different from the true one
    extra: dict = field(default_factory=dict)
    # Over-range samples written as the analyser does: {travel channel number: (from ms, to ms, "∞")}
    over_range: dict = field(default_factory=dict)


def truth():
    b = load_breaker(BREAKER_FILE)
    return b, b.design_parameters()


def curves(spec: Spec):
    """(t [s], travel mm, coils (6, n) [A], truth dict)."""
    b, p = truth()
    fs = spec.rate
    n = int(round(spec.length_ms * 1e-3 * fs))
    t = np.arange(n) / fs
    ops = {"CO": "CO", "O-CO": "OCO", "O": "O", "C": "C"}[spec.sequence]
    state_closed = ops[0] == "O"   # an O first starts closed
    mm = np.full(n, STROKE_MM if state_closed else 0.0)
    coils = np.zeros((6, n))
    events = []
    t_cmd = spec.t_first_ms * 1e-3
    for k, op in enumerate(ops):
        if op == "O":
            onset = t_cmd + spec.coil_to_motion_open_ms * 1e-3
            theta = OpeningCurves.at(t - onset, [p["AO"], p["BO"], p["DO"], p["EO"], 0.0], b)
            sel = t >= onset
            mm[sel] = STROKE_MM * (1.0 - theta[sel])
            rows = slice(3, 6)
        else:
            onset = t_cmd + spec.coil_to_motion_close_ms * 1e-3
            theta2 = ClosingCurves.at(np.maximum(t - onset, 0.0), [p["AC"], p["BC"], p["CC"], 0.0], b, p["DC"])
            theta2 = np.maximum.accumulate(theta2)  # the cam dwell holds the closed position
            sel = t >= onset
            mm[sel] = STROKE_MM * theta2[sel] / b.stroke
            rows = slice(0, 3)
        on = (t >= t_cmd) & (t < t_cmd + 0.06)
        coils[rows, on] = 1.4 * (1 - np.exp(-(t[on] - t_cmd) / 3e-3))
        events.append({"operation": "open" if op == "O" else "close", "command_s": t_cmd, "onset_s": onset})
        t_cmd += spec.gap_ms * 1e-3 if k == 0 or spec.sequence != "O-CO" else 0.0
        if spec.sequence == "O-CO" and k == 1:
            t_cmd += spec.gap_ms * 1e-3
    rng = np.random.default_rng(spec.seed)
    mm = mm + rng.normal(0, spec.noise_mm, n)
    coils = coils + np.abs(rng.normal(0, 0.005, coils.shape))
    return t, mm, coils, {"events": events, "params": p, "alpha0": b.alpha0}


def export_text(spec: Spec) -> tuple[str, dict]:
    """The export's text and its truth."""
    t, mm, coils, tr = curves(spec)
    n = t.size
    travel = np.zeros((6, n))
    for ch in spec.wired_travel:
        travel[ch - 1] = mm
    closed = mm > 0.8 * STROKE_MM
    res = np.where(closed, 48.0, 8000.0)
    cur = np.where(closed, 100.0, 0.0)
    peaks = {f"C{i + 1}": float(np.round(coils[i], 3).max()) for i in range(6)}
    tr["coil_peak_a"] = peaks
    lines = []
    if spec.header:
        rate_k = (spec.stated_rate or spec.rate) / 1e3
        lines += [
            "SAP ID,000000000000,",
            "HEADER:,",
            "Substation:,TEST,,SAP Equipment No.:,000000000000,,Test Date :,01-01-2026,,",
            "Bay :,401-  TEST,,Breaker Type :,SPRING-245,,Serial Number :,000000,,",
            "Oil Pressure :,NA,,Air Pressure :,NA,,Voltage (kV) :,245,,",
            "",
            "SETTINGS :,",
            f"Trigger Option :,DCRM,,Sampling Speed (kC) :,{rate_k:g},,Reistance Range uOhm :,8000,,",
            f"Plot Length(ms) :,{spec.length_ms:g},,Delay tco (ms) :,{spec.gap_ms:g},,Delay toc (ms) :,300,,",
            "T1 (mm) :,182.00,,T2 (mm) :,0.00,,T3 (mm) :,0.00,,",
            "Analog Channels :,Enabled,,Linkage Ratio :,1.49,,",
            "",
            "Travel Results\t:",
            "Contact Travel(T1)(mm) :,182.00,,Contact Travel(T2)(mm) :,0.00,,Contact Travel(T3)(mm) :,0.00,,",
            "Open -Rebound(T1)(mm) :,1.50,,Open - Rebound(T2)(mm) :,0.00,,",
            "Close - Datum Velocity (m/s)(T1) :,4.20,,Open - Datum Velocity (m/s)(T1) :,5.90,,",
            # the analyser's coil peak: the column's largest raw sample, as written in the table
            f"Coil Current (A)(C1) :,{peaks['C1']:.3f},,Coil Current (A)(C4) :,{peaks['C4']:.3f},,",
            "",
        ]
    pad = "," * 14
    lines += [pad + "".join("Close -Velocity (m/s) :,%.2f," % v for v in (4.2, 0, 0, 0, 0, 0)),
              pad + "".join("Open -Velocity (m/s) :,%.2f," % v for v in (5.9, 0, 0, 0, 0, 0)),
              pad + "TR1,,TR1,,NA,,NA,,NA,,NA,",
              pad + "RBreak1,,NA,,NA,,NA,,NA,,NA,"]
    names = ([f"Coil Current C{i} (A)" for i in range(1, 7)] + [""]
             + [f"Contact Travel T{i} (mm)" for i in range(1, 7)] + [""]
             + sum(([f"DCRM Res CH{i} in uOhm", f"DCRM Current CH{i} in Amp"] for i in range(1, 7)), []))
    lines.append(",".join(names) + ",")
    tail = "," if spec.trailing_comma else ""
    marks = {}  # (sample, travel row) -> the over-range spelling
    for ch, (a_ms, b_ms, word) in spec.over_range.items():
        for k in np.flatnonzero((t >= a_ms * 1e-3 - 1e-9) & (t <= b_ms * 1e-3 + 1e-9)):
            marks[(int(k), ch - 1)] = word
    for k in range(n):
        dcrm = [res[k], cur[k]] + [8000.0, 0.0] * 5
        lines.append(",".join(f"{c:.3f}" for c in coils[:, k]) + ", ,"
                     + ",".join(marks.get((k, j), f"{x:.2f}") for j, x in enumerate(travel[:, k])) + " ,,"
                     + ",".join(f"{x:.2f}" for x in dcrm) + tail)
    eol = "\r\n" if spec.crlf else "\n"
    return eol.join(lines) + eol, tr


def write_export(path, spec: Spec) -> dict:
    text, tr = export_text(spec)
    path.write_bytes(text.encode("utf-8"))
    return tr
