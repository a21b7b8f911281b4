"""The one error the diagnosis raises for bad input."""


class DiagnosisError(ValueError):
    """The captures cannot be diagnosed: the message says why, in words."""
