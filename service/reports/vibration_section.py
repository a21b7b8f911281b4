"""The condition report's trip-latch and coil-current section (issue 49): each latest operation's
latch time (or why none was read), its vibration events, and the coil currents of a record that
carries them beside the analyser's own peak."""

from __future__ import annotations

from service.display import significant

EVENT_WORDS = {"first_shock": "first shock (trip strike)", "latch_release": "latch release",
               "buffer_engagement": "buffer engagement", "end_stop": "end stop", "impact": "impact"}


def _ms(v, digits: int = 3) -> str:
    return "—" if v is None else significant(v * 1e3, digits)


def vibration_section(pdf, c) -> None:
    """Add the section to ``pdf`` (a ``ReportPDF``) from ``c.latest`` (a ``ReportContent``)."""
    ops = [(kind, op) for kind, op in c.latest.items() if op is not None]
    if not ops:
        return
    pdf.heading("Trip latch and coil currents")
    pdf.para("The latch time runs from the vibration's first shock (the trip armature striking the latch) to the "
             "start of shaft motion (the travel fit's onset); the shocks are found in the vibration's short-time "
             "energy against its own pre-trigger noise (docs/vibration.md). A time that cannot be read is left "
             "out with its reason, never estimated.", size=7.5)
    for kind, op in ops:
        word = "opening" if kind == "open" else "closing"
        ch = op.characteristics or {}
        latch = ch.get("latch_time_s")
        text = (f"Latest {word} #{op.operation_id}: latch time {_ms(latch)} ms." if latch is not None else
                f"Latest {word} #{op.operation_id}: no latch time: {ch.get('latch_time_reason') or 'no vibration read'}.")
        pdf.para(text, style="B")
        events = ch.get("vibration_events") or []
        if events:
            pdf.grid(("Vibration event", "Time from motion [ms]", "Peak [g]"),
                     [(EVENT_WORDS.get(e["name"], e["name"]), _ms(e["t_s"], 4),
                       significant(e["peak_g"], 3) + (" (clipped)" if e.get("clipped") else "")) for e in events],
                     (70, 45, 40))
            pdf.ln(1)
        coils = ch.get("coils") or []
        if coils:
            rows = []
            for k in coils:
                stated = k.get("analyser_peak_a")
                rows.append((k["channel"], significant(k["peak_current_a"], 4),
                             "—" if stated is None else f"{significant(stated, 4)} ({k['peak_difference_rel']:+.1%})",
                             _ms(k.get("armature_dip_s")), _ms(k.get("current_end_s"))))
            pdf.grid(("Coil", "Peak [A]", "Analyser's peak [A]", "Armature dip [ms]", "Current end [ms]"), rows,
                     (20, 25, 45, 35, 35))
            reasons = sorted({k.get("armature_dip_reason") or k.get("current_end_reason") for k in coils} - {None})
            if reasons:
                pdf.para("A dash: " + "; ".join(reasons) + ".", size=7)
            pdf.ln(1)
