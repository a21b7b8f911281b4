"""A breaker's spring setting from its stored close–open pairs, and its commissioning pair.

A closing and an opening of one breaker within :data:`PAIR_WINDOW_S` share one friction state
(a timing test's CO record, or a C then an O minutes apart); their fitted BO, BC and CC give
the nut setting and the friction (:mod:`service.mechanics.spring_setting`). The unit's own
spring rate moves every reading by one offset no pair can see; one pair recorded at a known
setting, the commissioning pair (``hvcb commission``, ``POST /api/v1/breakers/{id}/commissioning``,
the operation page's button), measures it. Without one, the reading is from the design seat
and its interval holds the spring-rate tolerance.
"""

from __future__ import annotations

import math
from datetime import timedelta

from sqlalchemy import select
from sqlalchemy.orm import Session

from ..mechanics.breaker import Breaker
from ..mechanics.spring_setting import PAIR_WINDOW_S, pair_reading, setting
from .models import OperationRow, SpringReferenceRow

PARAMETERS = {"open": ("BO",), "close": ("BC", "CC")}


class NoPair(ValueError):
    """The operation has no usable close–open partner: the message says why."""


def partner(session: Session, op: OperationRow) -> OperationRow | None:
    """The breaker's nearest operation of the other kind within :data:`PAIR_WINDOW_S`."""
    other = "close" if op.kind == "open" else "open"
    window = timedelta(seconds=PAIR_WINDOW_S)
    rows = session.scalars(select(OperationRow).where(
        OperationRow.breaker_id == op.breaker_id, OperationRow.kind == other,
        OperationRow.occurred_at >= op.occurred_at - window,
        OperationRow.occurred_at <= op.occurred_at + window)).all()
    if not rows:
        return None
    return min(rows, key=lambda r: (abs((r.occurred_at - op.occurred_at).total_seconds()), r.id))


def pair_of(session: Session, op: OperationRow) -> tuple[OperationRow, OperationRow]:
    """(opening, closing) of ``op``'s pair, both fitted; :class:`NoPair` in words otherwise."""
    mate = partner(session, op)
    if mate is None:
        raise NoPair(f"no {'closing' if op.kind == 'open' else 'opening'} of this breaker within "
                     f"{PAIR_WINDOW_S / 60:g} minutes of operation {op.id}: the setting needs a close–open pair")
    opening, closing = (op, mate) if op.kind == "open" else (mate, op)
    for row in (opening, closing):
        fit = row.fit
        word = "opening" if row.kind == "open" else "closing"
        if fit is None or fit.status != "done":
            why = (fit.failure_reason if fit is not None and fit.failure_reason else
                   f"its fit is {fit.status if fit else 'not queued'}")
            raise NoPair(f"the pair's {word} (operation {row.id}) has no fitted parameters: {why}")
        missing = [n for n in PARAMETERS[row.kind]
                   if not _finite((fit.parameters or {}).get(n)) or not _finite((fit.stderr or {}).get(n))]
        if missing:
            raise NoPair(f"the pair's {word} (operation {row.id}) has no {', '.join(missing)} with a standard error")
    return opening, closing


def reading(opening: OperationRow, closing: OperationRow, breaker: Breaker) -> dict:
    """The pair's reading from the design seat (:func:`~service.mechanics.spring_setting.pair_reading`)."""
    p = {"BO": opening.fit.parameters["BO"], "BC": closing.fit.parameters["BC"], "CC": closing.fit.parameters["CC"]}
    sd = {"BO": opening.fit.stderr["BO"], "BC": closing.fit.stderr["BC"], "CC": closing.fit.stderr["CC"]}
    return pair_reading(breaker, p["BO"], p["BC"], p["CC"], sd=sd)


def current_reference(session: Session, breaker_id: int) -> SpringReferenceRow | None:
    """The breaker's newest commissioning pair, if any."""
    return session.scalars(select(SpringReferenceRow).where(SpringReferenceRow.breaker_id == breaker_id)
                           .order_by(SpringReferenceRow.recorded_at.desc(), SpringReferenceRow.id.desc())
                           .limit(1)).first()


def record_reference(session: Session, op: OperationRow, breaker: Breaker, *, known_steps: float,
                     by: str) -> SpringReferenceRow:
    """Record ``op``'s pair as the breaker's commissioning pair at ``known_steps`` nut steps
    from the design seat. :class:`NoPair` when it has no fitted partner."""
    if not _finite(known_steps) or abs(known_steps) > 50:
        raise ValueError(f"the known setting must be a number of nut steps from the design seat "
                         f"(within ±50), got {known_steps!r}")
    opening, closing = pair_of(session, op)
    row = SpringReferenceRow(breaker_id=op.breaker_id, opening_id=opening.id, closing_id=closing.id,
                             known_steps=float(known_steps), reading=reading(opening, closing, breaker),
                             recorded_by=by[:200])
    session.add(row)
    session.flush()
    return row


def reference_dict(row: SpringReferenceRow) -> dict:
    return {"id": row.id, "breaker_id": row.breaker_id, "opening_id": row.opening_id,
            "closing_id": row.closing_id, "known_steps": row.known_steps, "reading": row.reading,
            "recorded_by": row.recorded_by, "recorded_at": row.recorded_at}


def setting_of(session: Session, op: OperationRow, breaker: Breaker) -> dict:
    """What the operation page shows: ``status`` ``ok`` with the setting (steps, ci95, nearest,
    friction, basis, the pair's operation ids and the reference's), or ``none`` with ``reason``."""
    try:
        opening, closing = pair_of(session, op)
    except NoPair as exc:
        return {"status": "none", "reason": str(exc)}
    r = reading(opening, closing, breaker)
    ref = current_reference(session, op.breaker_id)
    reference = None if ref is None else dict(ref.reading, known_steps=ref.known_steps)
    out = setting(r, breaker, reference=reference)
    out.update(status="ok", opening_id=opening.id, closing_id=closing.id,
               reference=None if ref is None else reference_dict(ref),
               is_reference=ref is not None and {ref.opening_id, ref.closing_id} == {opening.id, closing.id})
    return out


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)
