"""Which operation of a record to fit: an analyser's CO or O–CO test holds several."""

from __future__ import annotations

from drivers.capture import Capture

from ..acquisition.coil_trigger import detect_from_coils
from ..acquisition.trigger import TriggerSettings
from ..mechanics.breaker import Breaker
from .window import FitError, operation_word


def operation_capture(record: Capture, breaker: Breaker, operation: str, index: int = 0):
    """``(capture, offset_s, picked)``: the ``index``-th operation of kind ``operation`` cut from
    a record without a vibration channel that has coil currents (its command instant), with its
    start in the record's time [s] and a note of the choice; any other capture as it is."""
    if index < 0:
        raise FitError(f"--index must be 0 or more, got {index}")
    if record.vibration is not None or not record.aux_of("coil_current"):
        if index:
            raise FitError(f"{record.source or 'capture'}: --index picks among the operations of an "
                           "analyser record (coil currents, no vibration channel); this capture holds one")
        return record, 0.0, None
    found = detect_from_coils(record, TriggerSettings.from_breaker(breaker))
    kind = [op for op in found if op.operation == operation]
    word = operation_word(operation)
    listing = ", ".join(f"{operation_word(op.operation)} at {op.window_start_s - record.first_sample_index / op.sample_rate:.3f} s"
                        for op in found) or "no operation"
    if not kind:
        raise FitError(f"{record.source or 'capture'}: no {word} found in this record ({listing})")
    if index >= len(kind):
        raise FitError(f"{record.source or 'capture'}: --index {index} asks for {word} {index + 1}, but the record "
                       f"holds {len(kind)} ({listing}); --index counts from 0")
    op = kind[index]
    offset = (op.capture.first_sample_index - record.first_sample_index) / record.sample_rate
    picked = {"operation": operation, "index": index, "of": len(kind),
              "record_operations": [o.operation for o in found]}
    return op.capture, offset, picked


def upload_operations(record: Capture, breaker: Breaker, operation: str | None) -> list:
    """``[(capture, kind), ...]`` to store for an upload, in the record's order: every operation
    of an analyser record (a CO record: its closing and its opening), or only those of the kind
    ``operation`` names; any other capture as it is, with ``operation`` (None: inferred later)."""
    if record.vibration is not None or not record.aux_of("coil_current"):
        return [(record, operation)]
    found = detect_from_coils(record, TriggerSettings.from_breaker(breaker))
    if not found:
        raise FitError(f"{record.source or 'capture'}: no opening or closing found in this analyser record")
    picked = [(op.capture, op.operation) for op in found if operation in (None, op.operation)]
    if not picked:
        listing = "-".join(op.operation[0].upper() for op in found)
        raise FitError(f"{record.source or 'capture'}: no {operation_word(operation)} found in this record "
                       f"(it holds {listing})")
    return picked
