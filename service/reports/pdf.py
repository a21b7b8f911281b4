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
    return "—" if v is None else f"{v:.{digits}g}"


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
             + f". Verdict against the breaker file's limits: {overall(verdicts)}.", style="B")
    pdf.grid(("Characteristic", "Measured", "Limit", "Unit", "Result"),
             [(v.label, _g(v.value), v.limit_text, v.unit, v.result) for v in op.characteristic_verdicts],
             (55, 30, 45, 20, 30), result_col=4)
    pdf.ln(1.5)
    rows = []
    for v in op.parameter_verdicts:
        ci = op.ci95.get(v.name)
        rows.append((v.name, _g(v.value, 5), f"{ci[0]:.5g} to {ci[1]:.5g}" if ci else "—", v.limit_text, v.unit,
                     v.result))
    pdf.grid(("Fitted parameter", "Value", "95 % interval", "Limit", "Unit", "Result"), rows,
             (35, 25, 45, 35, 15, 25), result_col=5)


def _alarm_section(pdf: ReportPDF, c: ReportContent):
    pdf.heading("Alarms")
    active = c.active_alarms
    if active:
        pdf.para(f"Active now ({len(active)}):", style="B")
        pdf.grid(("Parameter", "Level", "State", "Raised", "Message"),
                 [(a.parameter, a.level.upper(), a.state + (f" (shelved until {_t(a.shelved_until)})"
                                                            if shelved_now(a, c.generated_at) else ""), _t(a.raised_at),
                   a.message) for a in active], (21, 16, 23, 40, 80))
    else:
        pdf.para("No active alarm.")
    if not c.alarms:
        pdf.para(f"No alarm raised in {c.window.words()}.")
        return
    pdf.ln(1)
    pdf.para(f"History and evidence ({len(c.alarms)} alarm(s) raised in {c.window.words()}, newest first):",
             style="B")
    rows = []
    for a in c.alarms:
        ev = a.evidence or {}
        cur = ev.get("current") or {}
        change = cur.get("change_rel")
        evidence = (f"{_g(cur.get('value'), 5)} vs expected {_g(cur.get('expected'), 5)}"
                    + (f" ({100 * change:+.1f} %)" if isinstance(change, (int, float)) else "")
                    + (f"; CUSUM {ev['statistic']:.3g} σ (alarm {ev['thresholds']['alarm']:.3g} σ)"
                       if isinstance(ev.get("statistic"), (int, float)) and ev.get("thresholds") else ""))
        life = [f"raised {_t(a.raised_at)}"]
        for act in c.alarm_actions.get(a.id, []):
            life.append(f"{act.action} {_t(act.at)} by {act.by}" + (f" ({act.reason})" if act.reason else ""))
        if a.acknowledged_at and not any(x.action.startswith("ack") for x in c.alarm_actions.get(a.id, [])):
            life.append(f"acknowledged {_t(a.acknowledged_at)} by {a.acknowledged_by}")
        if a.cleared_at and not any(x.action.startswith("clear") for x in c.alarm_actions.get(a.id, [])):
            life.append(f"cleared {_t(a.cleared_at)}")
        rows.append((f"#{a.id} {a.parameter}", a.level.upper(), a.state, "; ".join(life), evidence))
    pdf.grid(("Alarm", "Level", "State", "Lifecycle", "Evidence when raised"), rows, (20, 16, 22, 70, 52), size=7)


def _prognosis_section(pdf: ReportPDF, c: ReportContent):
    pdf.heading("Prognosis")
    if not c.prognoses:
        pdf.para("The breaker file has no maintenance [limits]: nothing to forecast (docs/prognosis.md).")
        return
    rows = []
    for p in c.prognoses:
        q, d = p.operations_to_limit, p.date_to_limit
        if p.status == "crossed":
            ops = "past the limit now"
        elif q is None:
            ops = "none within the horizon"
        elif q.median is None:   # no trend: the slope's 90 % interval holds zero
            ops = "no trend: not within the horizon" + ("" if q.p05 is None else f" (5 %: {q.p05:.0f})")
        else:
            low = "—" if q.p05 is None else f"{q.p05:.0f}"
            high = "beyond the horizon" if q.p95 is None else f"{q.p95:.0f}"
            ops = f"{q.median:.0f} ({low} to {high})"
        date = "—" if d is None or d.median is None else f"{d.median:%Y-%m-%d}"
        rows.append((p.parameter, p.limit_text, _g(p.limit, 5), _g(p.current, 5), ops, date,
                     p.status + (f": {p.reason}" if p.reason else "")))
    pdf.grid(("Parameter", "Limit as written", "Limit", "Now (comp.)", "Operations to limit, median (5–95 %)",
              "Date (median)", "Status"), rows, (18, 30, 17, 20, 40, 22, 33), size=7)
    pdf.figure(figures.fan_png(c.prognoses),
               "Projected level of each limited parameter (median and 5–95 % band) against its limit; dots: the "
               "temperature-compensated fits the trend is drawn through; dotted line: now.")


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
    verdicts = [v for op in c.latest.values() if op is not None
                for v in op.characteristic_verdicts + op.parameter_verdicts]
    pdf.ln(1)
    pdf.key_values([("Summary", f"{n['open']} openings and {n['close']} closings from {_t(n['first'])} to "
                                f"{_t(n['last'])}; {n['done']} fitted, {n['failed']} failed, {n['pending']} pending"),
                    ("Latest operations", f"{overall(verdicts)}: the latest opening and closing against the "
                                          "breaker file's limits"),
                    ("Alarms", _alarm_summary(c)),
                    ("Prognosis", _soonest(c.prognoses))])
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
    names = ", ".join(f"{a.parameter} {a.level}" + (" (shelved)" if a not in told else "") for a in active)
    if not told:
        return f"none annunciated: {len(active)} active, all shelved ({names})"
    level = "ALARM" if any(a.level == "alarm" for a in told) else "WARNING"
    shelved = len(active) - len(told)
    return f"{level}: {len(active)} active ({names})" + (f", {shelved} of them shelved" if shelved else "")


def figures_buckets() -> int:
    from .content import TREND_BUCKETS

    return TREND_BUCKETS


def _soonest(progs) -> str:
    if not progs:
        return "no maintenance limits in the breaker file"
    p = progs[0]
    q = p.operations_to_limit
    if p.status == "crossed":
        return f"{p.parameter} is past its limit ({p.limit_text}): service is due"
    if q is None or q.median is None:
        return f"no limit crossing expected within the horizon (soonest: {p.parameter}, {p.status})"
    d = p.date_to_limit
    when = f", about {d.median:%Y-%m-%d}" if d is not None and d.median is not None else ""
    return f"{p.parameter} reaches its limit ({p.limit_text}) in about {q.median:.0f} operations{when}"


def report_pdf(c: ReportContent, path: str | Path | None = None) -> bytes:
    """Render, and write to ``path`` when given (atomically: a reader never sees half a file)."""
    data = render(c)
    if path is not None:
        from service.durable import write_durably

        write_durably(Path(path), data, mode=0o644)  # a report is for sharing
    return data
