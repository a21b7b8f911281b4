"""What a drift of a watched parameter most likely means, and what to do about it: the words the
alarm line, the fleet, the condition report and the notifications share.

From the reduced model's terms (docs/models.md): DO is the buffer's damping, so it falls when the
buffer loses oil; BO is the opening spring's force net of the resistance, so it falls when the
spring relaxes or the friction grows; latch_time_s (the vibration's first shock to the start of
motion, service.vibration) grows when the trip latch's grease dries or dirt and corrosion stick it. Pure: no I/O.
"""

from __future__ import annotations

# (parameter, direction of the drift) -> the likely cause in words
CAUSES = {("DO", "falling"): "buffer oil leak",
          ("DO", "rising"): "buffer damping increase (oil thickening, or a blocked orifice)",
          ("BO", "falling"): "opening spring relaxation or more resistance",
          ("BO", "rising"): "less resistance or a spring pre-compression change",
          ("latch_time_s", "rising"): "the trip latch is slow (dried or dirty grease, corrosion)",
          ("latch_time_s", "falling"): "a faster trip latch (after lubrication, or a weaker latch spring)",
          ("buffer_ratio", "rising"): "the buffer's shock comes later than the travel explains (a worn or loose "
                                      "buffer mount, or the accelerometer moved)",
          ("buffer_ratio", "falling"): "the buffer's shock comes earlier than the travel explains (a worn or loose "
                                       "buffer mount, or the accelerometer moved)"}
# parameter -> what the maintenance planner should do once it nears or passes its limit
ACTIONS = {"DO": "Service the buffer (oil level and seals).",
           "BO": "Service the opening spring and its latch.",
           "AO": "Inspect the opening spring.",
           "EO": "Inspect the buffer's end stop.",
           "AC": "Service the closing spring.",
           "CC": "Service the closing drive (lubrication, latch).",
           "BC": "Inspect the linkage.",
           "latch_time_s": "The trip latch is slow: lubricate or clean the latch.",
           "buffer_ratio": "Inspect the buffer's mounting and the accelerometer's."}


def likely_cause(parameter: str, direction: str) -> str:
    """The likely cause of ``parameter`` drifting ``direction`` ("falling" | "rising")."""
    return CAUSES.get((parameter, direction), "a change in the mechanism")


def action(parameter: str) -> str:
    """What to do when ``parameter`` reaches its maintenance limit."""
    return ACTIONS.get(parameter, "Service is due.")
