"""Virtual prototypes: test instruments that simulate a breaker with effects the reduced models omit.

They are not the paper's physics (that is `service.mechanics`); they make captures whose truth is
known, for the gap diagnosis and the studies. `a` is the project's own, `b` was written from the
effect names alone (docs/prototype-b.md).
"""
