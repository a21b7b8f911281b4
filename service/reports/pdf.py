"""The condition report laid out as a PDF (fpdf2): what an offline analyser's test report shows
(identity, results against limits with a verdict, the curves) and what only a monitor knows
(trends, alarms with their lifecycle and evidence, the prognosis, the diagnosis), then the method.

Text is real text in an embedded DejaVu Sans (matplotlib ships it), so units such as s⁻² print
and ``pdftotext`` reads the report back; figures are PNGs from ``figures``.
"""

from __future__ import annotations

import io
from pathlib import Path

from fpdf import FPDF
from fpdf.fonts import FontFace

from service.display import parameter_label, plural, quantity, significant, signed_change, unit
from service.findings import action, likely_cause
from service.mechanics.nomenclature import OPENING
from service.storage.crud_alarms import annunciated, shelved_now

from . import figures
from .content import ReportContent
from .verdicts import FAIL, PASS, overall

TEXT_W = 180.0  # mm: A4 (210 mm) less 15 mm margins
RESULT_COLOURS = {PASS: (214, 240, 214), FAIL: (250, 210, 205)}


def _font_dir() -> Path:
    import matplotlib

    return Path(matplotlib.get_data_path()) / "fonts" / "ttf"


def _t(t) -> str:
    return "—" if t is None else f"{t:%Y-%m-%d %H:%M:%S} UTC"


def _g(v, digits: int = 4) -> str:
    """A number in plain notation with a minus sign, never 2.363e+04."""
    return significant(v, digits, grouping=True)


class ReportPDF(FPDF):
    def __init__(self, title: str):
        super().__init__(format="A4", unit="mm")
        self.report_title = title
        d = _font_dir()
        self.add_font("DejaVu", "", str(d / "DejaVuSans.ttf"))
        self.add_font("DejaVu", "B", str(d / "DejaVuSans-Bold.ttf"))
        self.add_font("DejaVu", "I", str(d / "DejaVuSans-Oblique.ttf"))
        self.set_margins(15, 15, 15)
        self.set_auto_page_break(True, margin=15)
        self.set_title(title)
        self.set_creator("hvcb")

    def footer(self):
        self.set_y(-10)
        self.set_font("DejaVu", "", 7)
        self.set_text_color(110)
        self.cell(0, 4, f"{self.report_title} · page {self.page_no()} of {{nb}}", align="C")
        self.set_text_color(0)

    # -- building blocks -------------------------------------------------------------------
    def heading(self, text: str, *, size: float = 12):
        if self.get_y() > 250:
            self.add_page()
        self.ln(2)
        self.set_font("DejaVu", "B", size)
        self.cell(0, 7, text, new_x="LMARGIN", new_y="NEXT")
        self.set_font("DejaVu", "", 8.5)

    def para(self, text: str, *, size: float = 8.5, style: str = ""):
        self.set_font("DejaVu", style, size)
        self.multi_cell(0, 4.2, text, new_x="LMARGIN", new_y="NEXT", align="L")
        self.set_font("DejaVu", "", 8.5)

    def key_values(self, rows):
        self.set_font("DejaVu", "", 8.5)
        with self.table(col_widths=(40, 140), first_row_as_headings=False, line_height=4.6,
                        borders_layout="HORIZONTAL_LINES", text_align="LEFT") as table:
            for k, v in rows:
                r = table.row()
                r.cell(k, style=FontFace(emphasis="BOLD"))
                r.cell(str(v))

    def grid(self, head, rows, widths, *, result_col: int | None = None, size: float = 8):
        """A table with a heading row; the ``result_col`` cell is coloured PASS / FAIL."""
        self.set_font("DejaVu", "", size)
        with self.table(col_widths=widths, line_height=4.4, text_align="LEFT", borders_layout="SINGLE_TOP_LINE",
                        headings_style=FontFace(emphasis="BOLD", fill_color=(235, 235, 235))) as table:
            h = table.row()
            for c in head:
                h.cell(c)
            for row in rows:
                r = table.row()
                for i, c in enumerate(row):
                    if i == result_col and c in RESULT_COLOURS:
                        r.cell(c, style=FontFace(emphasis="BOLD", fill_color=RESULT_COLOURS[c]))
                    else:
                        r.cell(str(c))
        self.set_font("DejaVu", "", 8.5)

    def figure(self, png: bytes | None, caption: str, *, width: float = TEXT_W, heading: str | None = None):
        """The figure with its caption below, on a new page when it does not fit (its
        ``heading`` goes with it)."""
        if png is None:
            return
        from PIL import Image

        with Image.open(io.BytesIO(png)) as im:
            h = width * im.height / im.width
        if self.get_y() + h + 8 + (12 if heading else 0) > self.h - self.b_margin:
            self.add_page()
        if heading:
            self.heading(heading)
        self.image(io.BytesIO(png), x=self.l_margin, w=width)
        self.set_font("DejaVu", "I", 7.5)
        self.multi_cell(0, 3.8, caption, new_x="LMARGIN", new_y="NEXT", align="L")
        self.set_font("DejaVu", "", 8.5)


def _latest_section(pdf: ReportPDF, c: ReportContent, kind: str):
    word = "opening" if kind == "open" else "closing"
    op = c.latest[kind]
    pdf.heading(f"Latest {word}")
    if op is None:
        pdf.para(f"No fitted {word} in {c.window.words()}.")
        return
    verdicts = op.characteristic_verdicts + op.parameter_verdicts
    pdf.para(f"Operation #{op.operation_id}, {_t(op.occurred_at)}; fit version {op.fit_version}, rms residual "
             f"{_g(op.rmse_rad * 1e3 if op.rmse_rad is not None else None, 3)} mrad"
             + ("" if op.identifiable is not False else "; NOT identifiable: the values are uncertain")
             + f". Against the breaker file's limits: {_verdict_words(overall(verdicts), verdicts)}.", style="B")
    pdf.grid(("Characteristic", "Measured", "Limit", "Unit", "Result"),
             [(v.label, _g(v.value), v.limit_text, v.unit, v.result) for v in op.characteristic_verdicts],
             (55, 30, 45, 20, 30), result_col=4)
    pdf.ln(1.5)
    rows = []
    for v in op.parameter_verdicts:
        ci = op.ci95.get(v.name)
        rows.append((parameter_label(v.name), _g(v.value, 5), f"{_g(ci[0], 5)} to {_g(ci[1], 5)}" if ci else "—",
                     v.limit_text, unit(v.name), v.result))
    pdf.grid(("Fitted parameter", "Value", "95 % interval", "Limit", "Unit", "Result"), rows,
             (52, 20, 38, 30, 15, 25), result_col=5)


def _verdict_words(result: str, verdicts) -> str:
    """PASS, or FAIL naming what fails."""
    if result != FAIL:
        return result
    failed = [v.label if v.name == v.label else parameter_label(v.name) for v in verdicts if v.result == FAIL]
    return f"FAIL ({', '.join(failed)} outside the limit)"


def _alarm_section(pdf: ReportPDF, c: ReportContent):
    pdf.heading("Alarms")
    active = c.active_alarms
    if active:
        pdf.para(f"Active now ({len(active)}):", style="B")
        pdf.grid(("Parameter", "Level", "State", "Raised", "Message"),
                 [(parameter_label(a.parameter), a.level.upper(), a.state + (f" (shelved until {_t(a.shelved_until)})"
                                                            if shelved_now(a, c.generated_at) else ""), _t(a.raised_at),
                   a.message) for a in active], (32, 15, 30, 35, 68))
    else:
        pdf.para("No active alarm.")
    if not c.alarms:
        pdf.para(f"No alarm raised in {c.window.words()}.")
        return
    pdf.ln(1)
    pdf.para(f"History and evidence ({plural(len(c.alarms), 'alarm')} raised in {c.window.words()}, newest first):",
             style="B")
    rows = []
    for a in c.alarms:
        ev = a.evidence or {}
        cur = ev.get("current") or {}
        change = cur.get("change_rel")
        u = unit(a.parameter)
        evidence = (f"{_g(cur.get('value'), 4)} {u} against the expected {_g(cur.get('expected'), 4)} {u}"
                    + (f" ({signed_change(change)})" if isinstance(change, (int, float)) else "")
                    + (f"; CUSUM {ev['statistic']:.3g} σ (alarm {ev['thresholds']['alarm']:.3g} σ)"
                       if isinstance(ev.get("statistic"), (int, float)) and ev.get("thresholds") else ""))
        life = [f"raised {_t(a.raised_at)}"]
        for act in c.alarm_actions.get(a.id, []):
            life.append(f"{act.action} {_t(act.at)} by {act.by}" + (f" ({act.reason})" if act.reason else ""))
        if a.acknowledged_at and not any(x.action.startswith("ack") for x in c.alarm_actions.get(a.id, [])):
            life.append(f"acknowledged {_t(a.acknowledged_at)} by {a.acknowledged_by}")
        if a.cleared_at and not any(x.action.startswith("clear") for x in c.alarm_actions.get(a.id, [])):
            life.append(f"cleared {_t(a.cleared_at)}")
        rows.append((f"#{a.id} {parameter_label(a.parameter)}", a.level.upper(), a.state, "; ".join(life), evidence))
    pdf.grid(("Alarm", "Level", "State", "Lifecycle", "Evidence when raised"), rows, (30, 14, 22, 58, 56), size=7)


def _prognosis_section(pdf: ReportPDF, c: ReportContent):
    pdf.heading("Prognosis")
    if not c.prognoses:
        pdf.para("The breaker file has no maintenance limits: nothing to forecast (docs/prognosis.md).")
        return
    rows = []
    for p in c.prognoses:
        q, d = p.operations_to_limit, p.date_to_limit
        kind = "openings" if p.parameter in OPENING else "closings"
        if p.status == "crossed":
            ops = "past the limit now"
        elif q is None or q.median is None:
            ops = "not expected within the horizon" + ("" if q is None or q.p05 is None
                                                        else f" (at the earliest in {q.p05:,.0f} {kind})")
        else:
            low = "—" if q.p05 is None else f"{q.p05:,.0f}"
            high = "beyond the horizon" if q.p95 is None else f"{q.p95:,.0f}"
            ops = f"{_operations(q.median, p.parameter)} ({low} to {high})"
        if p.status == "crossed":
            date = "now"
        elif d is not None and d.median is not None:
            date = f"{d.median:%Y-%m-%d}"
        elif q is not None and q.median is not None:
            date = "not known: too few days of operations to learn their rate"
        else:
            date = "—"
        rows.append((parameter_label(p.parameter), _limit_cell(c, p), quantity(p.current, p.parameter, 4), ops, date,
                     _status_words(p)))
    pdf.grid(("Parameter", "Limit", "Trend level", "Operations to the limit: median (5–95 %)",
              "Date (median)", "What it means"), rows, (26, 34, 20, 34, 22, 44), size=7)
    pdf.para("Trend level: the temperature-compensated trend at the latest fit, which the forecast starts from; "
             "the latest fit itself is in the tables above.", size=7)
    pdf.figure(figures.fan_png(c.prognoses, c.limit_words),
               "Projected level of each limited parameter (median and 5–95 % band) against its limit; dots: the "
               "temperature-compensated fits the trend is drawn through; dotted line: the latest fit.")


def _maintenance_section(pdf: ReportPDF, c: ReportContent):
    """The maintenance log (issue 50): each entry restarts what it touches."""
    pdf.heading("Maintenance log")
    if not c.maintenance:
        pdf.para("No maintenance logged: a level step in a trend stays a step (the breaker page's \"Maintenance "
                 "log\" or POST /api/v1/breakers/{name}/maintenance).")
        return
    rows = [(f"{e.done_at:%Y-%m-%d %H:%M} UTC", e.kind, e.done_by,
             "every parameter" if "*" in (e.parameters or []) else ", ".join(e.parameters or []), e.note or "—")
            for e in c.maintenance]
    pdf.grid(("Done", "What", "By", "Restarts", "Note"), rows, (30, 40, 30, 36, 44), size=7)
    pdf.para("An entry restarts the baseline, the alarms and the prognosis of the parameters it touches at the time "
             "the work was done.", size=7)


def _limit_cell(c: ReportContent, p) -> str:
    """The limit in words with its value(s) and unit: "25 % below the baseline: 31.78 s⁻¹"."""
    values = [lim["value"] for lim in (p.limits or []) if lim.get("value") is not None] or (
        [p.limit] if p.limit is not None else [])
    words = c.limit_words.get(p.parameter) or ""
    shown = " and ".join(quantity(v, p.parameter, 4) for v in sorted(values))
    return f"{words}: {shown}" if words and shown else (words or shown or "—")


def _status_words(p) -> str:
    """The prognosis's status as a sentence, once ("no trend" is not repeated)."""
    if p.status == "crossed":
        return f"Past the limit: service is due. {action(p.parameter)}"
    if p.status == "no trend":
        reason = (p.reason or "").removeprefix("no trend: ").removeprefix("no trend")
        return "No trend" + (f": {reason}" if reason else "") + "."
    return "A crossing is expected: plan the service."


def _diagnosis_section(pdf: ReportPDF, c: ReportContent):
    pdf.heading("Last diagnosis")
    d = c.diagnosis
    if d is None:
        pdf.para("No gap diagnosis has been asked for this breaker (the breaker page's \"Diagnose the last N "
                 "operations\", docs/diagnosis.md).")
        return
    prob = f", probability {d['probability']:.2f}" if isinstance(d.get("probability"), (int, float)) else ""
    pdf.key_values([("Diagnosis", f"#{d['id']}, {d['status']}, of the last {d['captures']} {d['operation']} "
                                   f"operation(s), asked {_t(d['requested_at'])}"),
                    ("Answer", (d["answer"] or "—") + prob),
                    ("In words", d["message"] or "—")])


def render(c: ReportContent) -> bytes:
    """The condition report as PDF bytes."""
    b = c.breaker
    pdf = ReportPDF(f"Condition report: {b.name}")
    pdf.add_page()
    pdf.set_font("DejaVu", "B", 16)
    pdf.cell(0, 9, f"Condition report: {b.name}", new_x="LMARGIN", new_y="NEXT")
    pdf.set_font("DejaVu", "", 9)
    pdf.cell(0, 5, f"Tag {b.tag} · covering {c.window.words()} · generated {_t(c.generated_at)} by hvcb",
             new_x="LMARGIN", new_y="NEXT")
    n = c.counts
    pdf.ln(1)
    pdf.key_values([("Finding", finding(c)),
                    ("Operations", f"{plural(n['open'], 'opening')} and {plural(n['close'], 'closing')} from "
                                   f"{_t(n['first'])} to {_t(n['last'])}; {n['done']:,} fitted, {n['failed']:,} failed, "
                                   f"{n['pending']:,} pending"),
                    ("Latest operations", _latest_words(c)),
                    ("Alarms", _alarm_summary(c)),
                    ("Prognosis", _soonest(c))])
    pdf.heading("Breaker")
    pdf.key_values(c.identity)
    if c.file_problem:
        pdf.para(f"The stored breaker file does not load: {c.file_problem}", style="B")
    _latest_section(pdf, c, "open")
    _latest_section(pdf, c, "close")
    pdf.figure(figures.curves_png(c.latest),
               "Travel of the latest opening and closing: measured (solid) and the fitted model (dashed).")
    for kind in ("open", "close"):
        op = c.latest[kind]
        if op is not None and op.curve is None and op.curve_note:
            pdf.para(f"Latest {'opening' if kind == 'open' else 'closing'}: no curve, {op.curve_note}.", size=7.5)
    from .vibration_section import vibration_section  # the trip latch and the coil currents (issue 49)

    vibration_section(pdf, c)
    if c.trends:
        pdf.figure(figures.trends_png(c.trends), heading="Fitted parameters over time", caption=
                   "Each fitted parameter with its 95 % interval (band), the drift detector's baseline (dashed) and "
                   "the breaker file's maintenance limits (red); dotted vertical lines: alarms raised (at the "
                   "operation that raised them). Long histories are "
                   "drawn as the minimum and maximum of each of "
                   f"{figures_buckets()} buckets, so no excursion is lost.")
    else:
        pdf.heading("Fitted parameters over time")
        pdf.para(f"No fitted parameter in {c.window.words()}.")
    _alarm_section(pdf, c)
    _prognosis_section(pdf, c)
    _maintenance_section(pdf, c)
    _diagnosis_section(pdf, c)
    pdf.heading("Method and version")
    pdf.key_values(c.method)
    return bytes(pdf.output())


def _alarm_summary(c: ReportContent) -> str:
    """The breaker's alarm status as the page counts it: shelved alarms are listed, not counted."""
    active = c.active_alarms
    if not active:
        return "no active alarm"
    told = annunciated(active, c.generated_at)
    names = ", ".join(f"{parameter_label(a.parameter)} {a.level}" + (" (shelved)" if a not in told else "")
                      for a in active)
    if not told:
        return f"none annunciated: {len(active)} active, all shelved ({names})"
    level = "ALARM" if any(a.level == "alarm" for a in told) else "WARNING"
    shelved = len(active) - len(told)
    return f"{level}: {len(active)} active ({names})" + (f", {shelved} of them shelved" if shelved else "")


def _latest_words(c: ReportContent) -> str:
    """Each latest operation's verdict on its own: "opening #78 FAIL (…); closing #76 PASS"."""
    parts = []
    for kind, word in (("open", "opening"), ("close", "closing")):
        op = c.latest[kind]
        if op is None:
            parts.append(f"no fitted {word}")
            continue
        verdicts = op.characteristic_verdicts + op.parameter_verdicts
        parts.append(f"{word} #{op.operation_id} {_verdict_words(overall(verdicts), verdicts)}")
    return "; ".join(parts) + ", against the breaker file's limits"


def figures_buckets() -> int:
    from .content import TREND_BUCKETS

    return TREND_BUCKETS


def _soonest(c: ReportContent) -> str:
    progs = c.prognoses
    if not progs:
        return "no maintenance limits in the breaker file"
    p = progs[0]
    q = p.operations_to_limit
    who = parameter_label(p.parameter)
    limit = c.limit_words.get(p.parameter) or p.limit_text
    if p.status == "crossed":
        return f"{who} is past its limit ({limit}): service is due"
    if q is None or q.median is None:
        return f"no limit crossing expected within the horizon (soonest: {who}, {p.status})"
    if q.median < 0.5:
        return f"{who} is at its limit ({limit}) now: service is due"
    d = p.date_to_limit
    when = f", about {d.median:%Y-%m-%d}" if d is not None and d.median is not None else ""
    return f"{who} reaches its limit ({limit}) in about {_operations(q.median, p.parameter)}{when}"


def _operations(n: float, parameter: str) -> str:
    """Whole operations of the parameter's kind: "1 opening", "12 closings"."""
    return plural(int(round(n)), "opening" if parameter in OPENING else "closing")


def finding(c: ReportContent) -> str:
    """What the report finds, in a sentence or two an asset manager can act on: a limit passed, a
    drift with its likely cause and what to do, a limit expected soon, a failed check, or none."""
    text = _finding(c)
    return text[0].upper() + text[1:]


def _finding(c: ReportContent) -> str:
    crossed = [p for p in c.prognoses if p.status == "crossed"]
    if crossed:
        p = crossed[0]
        cause = likely_cause(p.parameter, p.direction or "")
        return (f"{parameter_label(p.parameter)} is past its maintenance limit "
                f"({c.limit_words.get(p.parameter) or p.limit_text}): trend level "
                f"{quantity(p.current, p.parameter, 3)}. Likely cause: {cause}. {action(p.parameter)}")
    told = annunciated(c.active_alarms, c.generated_at) if c.active_alarms else []
    if told:
        a = told[0]
        ev = a.evidence or {}
        direction = ev.get("drift_direction", "")
        ahead = next((p for p in c.prognoses if p.parameter == a.parameter and p.operations_to_limit is not None
                      and p.operations_to_limit.median is not None), None)
        when = ""
        if ahead is not None:
            n = ahead.operations_to_limit.median
            when = (" It is at its maintenance limit now." if n < 0.5 else
                    f" It is expected to reach its maintenance limit in about {_operations(n, a.parameter)}.")
        return (f"{parameter_label(a.parameter)} is {direction or 'drifting'} ({a.level}). Likely cause: "
                f"{likely_cause(a.parameter, direction)}.{when} {action(a.parameter)}")
    soon = [p for p in c.prognoses if p.operations_to_limit is not None and p.operations_to_limit.median is not None]
    if soon:
        return f"No active alarm; {_soonest(c)}. Plan the service."
    failed = [(kind, op) for kind, op in c.latest.items() if op is not None
              and overall(op.characteristic_verdicts + op.parameter_verdicts) == FAIL]
    if failed:
        kind, op = failed[0]
        word = "opening" if kind == "open" else "closing"
        return (f"The latest {word} (#{op.operation_id}) fails a limit of the breaker file: "
                f"{_verdict_words(FAIL, op.characteristic_verdicts + op.parameter_verdicts)}. Check the mechanism.")
    return ("No finding: no active alarm, the latest operations meet the breaker file's limits and no limit "
            "crossing is expected within the horizon.")


def report_pdf(c: ReportContent, path: str | Path | None = None) -> bytes:
    """Render, and write to ``path`` when given (atomically: a reader never sees half a file)."""
    data = render(c)
    if path is not None:
        from service.durable import write_durably

        write_durably(Path(path), data, mode=0o644)  # a report is for sharing
    return data
