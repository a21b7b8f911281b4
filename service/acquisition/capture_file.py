"""Service-facing entry for reading captures; the format-level reader lives in
``drivers.capture_file`` (and ``drivers.comtrade``) so drivers need not import the service."""

from drivers.capture_file import (  # noqa: F401
    MAX_SAMPLES,
    TRAVEL_UNITS,
    VIBRATION_UNITS,
    analyser_capture,
    check_finite,
    load_capture_bytes,
    load_comtrade_bytes,
    parse_csv,
    read_capture,
    read_comtrade,
    read_csv,
    record_to_capture,
)
