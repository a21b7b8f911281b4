"""A close–open pair written straight into the fit table: the closing's BC, CC and the opening's
BO of the reference design at a known nut setting and friction, for the spring-setting tests."""

from __future__ import annotations

from datetime import datetime, timedelta


def pair_parameters(b, steps: float, friction: float = 1.0, kappa: float = 1.0) -> dict:
    """The exact BO, BC, CC (Eqs. 8, 12) of a unit with spring rate κ·kO at ``steps`` nut steps."""
    from service.mechanics.spring_setting import NUT_STEP_M

    kO = kappa * b.kO
    P = kO * steps * NUT_STEP_M * b.rO
    return {"BO": (kO * b.xO1 * b.rO + P - friction * b.TOf) / b.J2, "BC": b.J2 / b.J1,
            "CC": (friction * b.TCf + kO * b.xO0 * b.rO + P) / b.J2}


def store_pair(Session, b, *, breaker_id: int, at: datetime, steps: float, friction: float = 1.0,
               kappa: float = 1.0, key: str = "pair", gap: timedelta = timedelta(seconds=0.3)) -> tuple[int, int]:
    """A closing at ``at`` and an opening ``gap`` later, both fitted; returns (closing id, opening id)."""
    from service.storage import crud

    p = pair_parameters(b, steps, friction, kappa)
    design = b.design_parameters()
    ids = []
    for kind, when, params, err in (
            ("close", at, {"AC": design["AC"], "BC": p["BC"], "CC": p["CC"]}, {"AC": 200.0, "BC": 0.005, "CC": 40.0}),
            ("open", at + gap, {"AO": design["AO"], "BO": p["BO"], "DO": design["DO"], "EO": design["EO"]},
             {"AO": 60.0, "BO": 20.0, "DO": 0.5, "EO": 50.0})):
        with Session() as s, s.begin():
            op, _ = crud.create_operation(s, capture_key=f"{key}-{kind}-{breaker_id}", breaker_id=breaker_id,
                                          kind=kind, occurred_at=when, source="replay", capture_path="/nonexistent.cfg",
                                          capture_sha256="0" * 64, flags=[], sample_rate=10_000.0, n_samples=4000)
            crud.claim_fit(s, operation_id=op.id, worker="test")
            crud.store_fit_result(s, operation_id=op.id, curve=None, result={
                "parameters": params, "stderr": err,
                "ci95": {k: [v - 1.96 * err[k], v + 1.96 * err[k]] for k, v in params.items()},
                "identifiable": True})
            ids.append(op.id)
    return ids[0], ids[1]


__all__ = ["pair_parameters", "store_pair"]
