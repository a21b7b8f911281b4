"""Driver exceptions. The message says what is wrong in words for the person wiring the DAQ."""

from __future__ import annotations


class DriverError(OSError):
    """The DAQ link failed in a way that retrying will not fix (bad URL, wrong device)."""


class CaptureDownloadError(DriverError):
    """A Modbus capture could not be downloaded intact; the driver retries it on the next poll."""
