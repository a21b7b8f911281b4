"""Errors reach operators in words: the error's own words, with what kind of failure it is when
they alone do not say it; never a Python class name."""

from __future__ import annotations

import asyncio
import socket
import sqlite3

import httpx
from sqlalchemy.exc import OperationalError

from service.errors import in_words


def test_link_and_database_errors_in_words():
    assert in_words(ConnectionRefusedError(111, "Connection refused")) == "connection refused"
    assert in_words(TimeoutError()) == "timed out"
    assert in_words(socket.gaierror(-2, "Name or service not known")) == "host name not found: Name or service not known"
    assert in_words(httpx.ConnectError("[Errno 111] Connection refused")) == "cannot connect: Connection refused"
    assert in_words(OperationalError("SELECT 1", {}, sqlite3.OperationalError("database is locked"))) \
        == "database is locked"  # the driver's words under SQLAlchemy's wrapper
    assert in_words(asyncio.IncompleteReadError(b"", 10)).startswith("the connection closed in the middle of a reply")


def test_other_errors_keep_their_words_and_never_show_a_class_name():
    assert in_words(ValueError("sample rate must be positive")) == "sample rate must be positive"
    assert in_words(KeyError("DO")) == "missing entry: 'DO'"
    assert in_words(FileNotFoundError(2, "No such file or directory", "a.cfg")) \
        == "file not found: No such file or directory: 'a.cfg'"
    for exc in (RuntimeError(), ValueError(""), ZeroDivisionError("division by zero")):
        said = in_words(exc)
        assert said and type(exc).__name__ not in said and "\n" not in said


def test_a_fit_that_fails_unexpectedly_says_so_in_words_and_logs_the_traceback(caplog):
    from service.jobs.fit import failure_reason

    try:
        {}["DO"]
    except KeyError as exc:
        said = failure_reason(exc)
    assert said == "unexpected failure: missing entry: 'DO'"
    (record,) = [r for r in caplog.records if r.name == "hvcb.jobs"]
    assert record.exc_info is not None  # developers still get the traceback in the log
