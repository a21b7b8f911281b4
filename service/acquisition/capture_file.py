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


def breaker_reading(breaker) -> dict:
    """The capture reader's keywords for ``breaker``: its channel names and its mm mapping
    (``to_rad`` of the breaker file's ``[travel]`` section, None when it has none)."""
    tmap = getattr(breaker, "travel_map", None)
    return {"travel_channel": breaker.channels.get("travel", "travel"),
            "vibration_channel": breaker.channels.get("vibration", "vibration"),
            "to_rad": tmap.to_rad if tmap is not None else None}


def read_stored_capture(path, breaker):
    """Read a stored capture of ``breaker`` with its breaker file's channel names.

    Uploads are stored byte for byte as sent, so they carry the breaker's own channel names
    (the upload was read with them before it was accepted). A capture hvcb wrote itself (a
    DAQ's, service/acquisition/comtrade_writer.py) names its channels ``travel`` and
    ``vibration``: those are read when the breaker's names are absent.
    """
    from drivers.capture import CaptureError

    kw = breaker_reading(breaker)
    travel = kw["travel_channel"]
    try:
        return read_capture(path, **kw)
    except CaptureError as exc:
        if travel.lower() == "travel" or "no channel named" not in str(exc):
            raise
        return read_capture(path)
