"""Process pools whose workers leave Ctrl-C to the parent.

A terminal's Ctrl-C (SIGINT) reaches the whole foreground process group. Without this, every
pool worker of ``hvcb demo`` or a study dies printing a ``KeyboardInterrupt`` traceback while the
parent is still shutting down cleanly; the parent alone decides when its workers stop.
"""

from __future__ import annotations

import multiprocessing
import signal
from concurrent.futures import ProcessPoolExecutor

_SIGINT = {signal.SIGINT}


def _start_worker(initializer) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _SIGINT)  # one held during start-up is dropped now
    if initializer is not None:
        initializer()


class _Pool(ProcessPoolExecutor):
    def submit(self, fn, /, *args, **kwargs):
        # Workers are started inside submit and inherit this thread's signal mask: with SIGINT
        # blocked, a Ctrl-C during a worker's imports waits until _start_worker ignores it.
        # (A blocked SIGINT on the caller's own thread is delivered when the mask is restored.)
        old = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGINT)
        try:
            return super().submit(fn, *args, **kwargs)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)

    def terminate_workers(self, timeout_s: float = 2.0) -> None:
        """Stop now: cancel the queued jobs and end the running ones (SIGTERM). Without it, the
        interpreter's exit waits for every running job (concurrent.futures joins its workers),
        which is a whole fit's time after a Ctrl-C. (Python 3.14 has this built in.)"""
        processes = list((self._processes or {}).values())
        self.shutdown(wait=False, cancel_futures=True)
        for p in processes:
            if p.is_alive():
                p.terminate()
        for p in processes:
            p.join(timeout_s)
        # the executor's manager thread ends once it sees its workers gone: wait for it too, so
        # a stopped pool leaves no thread behind (the stdlib names it only "Thread-N")
        manager = getattr(self, "_executor_manager_thread", None)
        if manager is not None:
            manager.join(timeout_s)


def process_pool(max_workers: int, *, initializer=None, start_method: str | None = "spawn") -> ProcessPoolExecutor:
    """A ``ProcessPoolExecutor`` of ``max_workers`` that ignore SIGINT from their first instruction.

    ``start_method`` is "spawn" by default: the service runs threads, which fork would copy in
    the middle of a lock. ``None`` keeps the platform's default (the CLI studies). ``initializer``
    (a module-level function) runs in each worker after the signal is set.
    """
    context = multiprocessing.get_context(start_method) if start_method else None
    return _Pool(max_workers=max_workers, mp_context=context, initializer=_start_worker, initargs=(initializer,))
