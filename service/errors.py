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


# The standard library's errors that reach an operator (DAQ links, the central server, the
# database, files), named in words; the first class in an exception's MRO found here wins.
_WORDS = {
    "ConnectionRefusedError": "connection refused",
    "ConnectionResetError": "connection reset by the other end",
    "ConnectionAbortedError": "connection aborted",
    "BrokenPipeError": "connection closed by the other end",
    "IncompleteReadError": "the connection closed in the middle of a reply",
    "EOFError": "the connection closed in the middle of a reply",
    "TimeoutError": "timed out",
    "ReadTimeout": "timed out waiting for the reply",
    "ConnectTimeout": "timed out connecting",
    "ConnectError": "cannot connect",
    "gaierror": "host name not found",
    "FileNotFoundError": "file not found",
    "PermissionError": "permission denied",
    "IsADirectoryError": "a folder where a file was expected",
    "MemoryError": "out of memory",
    "KeyError": "missing entry",
    "IndexError": "index out of range",
}
_ERRNO = __import__("re").compile(r"^\[Errno -?\d+\]\s*")


def in_words(exc: BaseException) -> str:
    """One line saying what went wrong, for an operator: the words of the error itself (or of
    the database driver under SQLAlchemy's wrapper), prefixed by what kind of failure it is when
    the words alone do not say; never a Python class name."""
    exc = getattr(exc, "orig", None) or exc
    text = _ERRNO.sub("", (str(exc) or getattr(exc, "strerror", None) or "").strip())
    text = text.splitlines()[0].strip() if text else ""
    kind = next((_WORDS[c.__name__] for c in type(exc).__mro__ if c.__name__ in _WORDS), None)
    if kind is None:
        return text or "an unexpected error (the service log has the details)"
    if not text or text.lower() == kind or text.lower().startswith(kind):
        return kind
    return f"{kind}: {text}"
