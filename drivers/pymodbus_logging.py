"""Keep pymodbus's own log lines out of the output.

pymodbus logs connection trouble at ERROR level and appends a hex dump of the last frames
("Cancel send, because not connected!" followed by raw bytes) whenever a client or server is
torn down mid-request. The drivers count and report their own retries, reconnects and CRC
errors, so those lines only add noise. Only the level of the ``pymodbus`` logger is set, and
only when nobody configured it: an operator who asks for pymodbus's debug output still gets it.
"""

from __future__ import annotations

import logging

PYMODBUS_LOGGER = "pymodbus"


def quiet_pymodbus(level: int = logging.CRITICAL) -> None:
    """Show only pymodbus messages at ``level`` or above, unless its logger was configured."""
    logger = logging.getLogger(PYMODBUS_LOGGER)
    if logger.level == logging.NOTSET:
        logger.setLevel(level)
