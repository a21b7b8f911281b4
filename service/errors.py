"""Errors whose message is meant for the person at the terminal or the API client."""


class UserError(Exception):
    """A one-line, engineer-readable reason why a command cannot proceed."""


# An absolute POSIX or Windows path: a slash- or drive-rooted run of path characters with at
# least one separator inside. Only its last part (the file name) is kept.
_PATH = __import__("re").compile(r"(?<![\w.:/])(?:[A-Za-z]:\\|/)(?:[^\s'\"/\\,;:()]+[/\\])+([^\s'\"/\\,;:()]*)")


def redact_paths(text: str | None) -> str | None:
    """``text`` with every absolute server path cut to its file name: answers to readers and
    operators must not tell where the service keeps its files (docs/security.md, D11)."""
    if not text:
        return text
    return _PATH.sub(lambda m: m.group(1) or "(a server folder)", text)
