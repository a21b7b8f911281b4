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


def read_stored_capture(path, breaker):
    """Read a stored capture of ``breaker`` with its breaker file's channel names.

    Uploads are stored byte for byte as sent, so they carry the breaker's own channel names
    (the upload was read with them before it was accepted). A capture hvcb wrote itself (a
    DAQ's, service/acquisition/comtrade_writer.py) names its channels ``travel`` and
    ``vibration``: those are read when the breaker's names are absent.
    """
    from drivers.capture import CaptureError

    travel = breaker.channels.get("travel", "travel")
    vibration = breaker.channels.get("vibration", "vibration")
    try:
        return read_capture(path, travel_channel=travel, vibration_channel=vibration)
    except CaptureError as exc:
        if travel.lower() == "travel" or "no channel named" not in str(exc):
            raise
        return read_capture(path)
