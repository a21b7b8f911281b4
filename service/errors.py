"""Errors whose message is meant for the person at the terminal or the API client."""


class UserError(Exception):
    """A one-line, engineer-readable reason why a command cannot proceed."""
