"""One executor interface for fit jobs, with a local process pool and a Celery backend."""

from .base import Executor, make_executor

__all__ = ["Executor", "make_executor"]
