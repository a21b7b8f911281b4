"""hvcb: condition monitoring for spring-operated HV circuit-breaker mechanisms."""

__version__ = "0.1.0"
