"""The analyser export layouts hvcb knows. Add one here (see docs/drivers.md)."""

from __future__ import annotations

from .profile import COIL, DCRM_CURRENT, RESISTANCE, TRAVEL, Column, HeaderValue, Profile

_CH_T = r"\((?P<ch>T\d+)\)"
_CH_C = r"\((?P<ch>C\d+)\)"

# CIBANO/TM1800-style timing + DCRM export (shared/realworld/analyser-csv/README.md): a header
# of "Key :,value,," pairs, two per-channel velocity lines, two label lines, then a table of
# six coil currents, six contact travels and six DCRM resistance/current pairs with blank
# separator columns and a trailing comma. Bare exports start at the velocity lines.
TIMING_DCRM_26 = Profile(
    name="timing/DCRM analyser CSV (coil C1-C6, travel T1-T6, DCRM CH1-CH6)",
    recognise=(r"Coil\s*Current\s*C\d+\s*\(A\)", r"Contact\s*Travel\s*T\d+\s*\(mm\)"),
    columns=(
        Column(r"Coil\s*Current\s*C(?P<n>\d+)\s*\(A\)", COIL, "C{n}", "A"),
        Column(r"Contact\s*Travel\s*T(?P<n>\d+)\s*\(mm\)", TRAVEL, "T{n}", "mm"),
        Column(r"DCRM\s*Res\s*CH(?P<n>\d+)\s*in\s*(uOhm|µOhm|micro\s*Ohm)", RESISTANCE, "R{n}", "uOhm"),
        Column(r"DCRM\s*Current\s*CH(?P<n>\d+)\s*in\s*Amps?", DCRM_CURRENT, "I{n}", "A"),
    ),
    # "kC": thousands of samples per second (the analyser's "kilo-conversions"), i.e. kS/s.
    rate={r"Sampling Speed ?\(kC\)": 1e3, r"Sampling (Speed|Rate) ?\(kS/s\)": 1e3,
          r"Sampling (Speed|Rate) ?\(Hz\)": 1.0},
    metadata=(
        HeaderValue(r"Substation", "station"),
        HeaderValue(r"Bay", "bay"),
        HeaderValue(r"Breaker Type", "breaker_type"),
        HeaderValue(r"Serial Number", "serial_number"),
        HeaderValue(r"Manufacturer", "manufacturer"),
        HeaderValue(r"Voltage \(kV\)", "rated_voltage_kv", "kV"),
        HeaderValue(r"Test Date", "test_date", date=True),
        HeaderValue(r"Trigger Option", "trigger_option"),
        HeaderValue(r"Plot Length ?\(ms\)", "plot_length_ms", "ms"),
        HeaderValue(r"Delay tco \(ms\)", "t_co_ms", "ms"),
        HeaderValue(r"Delay toc \(ms\)", "t_oc_ms", "ms"),
        HeaderValue(r"Linkage Ratio", "linkage_ratio", "-"),
        HeaderValue(r"(?P<ch>T\d+) \(mm\)", "travel_setting_mm", "mm"),
        HeaderValue(r"Electric Stroke Length (?P<ch>T\d+)", "electric_stroke_length", "mm"),
    ),
    results=(
        HeaderValue(r"Mechanism Travel" + _CH_T + r"\(mm\)", "mechanism_travel_mm", "mm"),
        HeaderValue(r"Contact Travel" + _CH_T + r"\(mm\)", "contact_travel_mm", "mm"),
        HeaderValue(r"Close - Datum Velocity \(m/s\)" + _CH_T, "close_datum_velocity_m_s", "m/s"),
        HeaderValue(r"Open - Datum Velocity \(m/s\)" + _CH_T, "open_datum_velocity_m_s", "m/s"),
        HeaderValue(r"Close - Over Travel" + _CH_T + r"\(mm\)", "close_over_travel_mm", "mm"),
        HeaderValue(r"Open - Rebound" + _CH_T + r"\(mm\)", "open_rebound_mm", "mm"),
        HeaderValue(r"Coil Current \(A\)" + _CH_C, "coil_current_peak_a", "A"),
    ),
    velocity_lines=(
        HeaderValue(r"Close - Velocity \(m/s\)", "close_velocity_m_s", "m/s"),
        HeaderValue(r"Open - Velocity \(m/s\)", "open_velocity_m_s", "m/s"),
    ),
    plot_length=r"Plot Length ?\(ms\)",
    stated_stroke=("contact_travel_mm", "travel_setting_mm"),
)

PROFILES = (TIMING_DCRM_26,)
