"""The vibration channel read: each operation's key moments and the trip latch's time (events),
the breaker's own healthy fingerprint and each operation's shift from it (fingerprint), and the
coil currents of analyser records (coils). See docs/vibration.md.
"""

from .coils import coil_results, record_coils
from .characteristics import unread, vibration_characteristics
from .events import FALSE_DETECTION_RATE, VibrationError, VibrationEvents, detect_events
from .fingerprint import Fingerprint, envelope

__all__ = ["FALSE_DETECTION_RATE", "coil_results", "record_coils", "Fingerprint", "envelope", "VibrationError", "VibrationEvents", "detect_events", "unread",
           "vibration_characteristics"]
