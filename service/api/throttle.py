"""Throttling of failed credentials (API keys and web sign-ins), per client address.

Each address gets ``free_failures`` wrong credentials for free. After that every further
failure costs ``delay = base_s * 2**k`` seconds (k = failures past the free ones, capped at
``max_s``): the wrong answer itself is held back ``delay``, and the address may not try again
for ``delay`` more; any attempt from the address before then is answered 429 with Retry-After. A success from the address, or
``forget_s`` without failures, clears it. A warning is logged when an address is first
throttled and at every doubling of its failures.

Why this never locks out the real admin: a right key is always checked and accepted, even from
a blocked address (the real admin behind the same NAT address as an attacker); a blocked address
only learns "wait" for a wrong one, and the admin's success does not unblock it. Keys are 256-bit random values: the throttle limits
noise and load, not the odds of guessing one (nil either way).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

log = logging.getLogger("hvcb.throttle")

MAX_ADDRESSES = 100_000  # memory bound: ~100 bytes an address


@dataclass
class _Record:
    failures: int = 0
    last_failure: float = 0.0
    blocked_until: float = 0.0


class AuthThrottle:
    def __init__(self, *, free_failures: int = 5, base_s: float = 0.5, max_s: float = 60.0,
                 forget_s: float = 900.0, clock=time.monotonic):
        self.free_failures, self.base_s, self.max_s, self.forget_s = free_failures, base_s, max_s, forget_s
        self._clock = clock
        self._records: dict[str, _Record] = {}
        self._lock = threading.Lock()

    @classmethod
    def from_settings(cls, srv) -> AuthThrottle:
        return cls(free_failures=srv.auth_free_failures, base_s=srv.auth_delay_base_s,
                   max_s=srv.auth_delay_max_s, forget_s=srv.auth_forget_s)

    def _record(self, address: str, now: float) -> _Record | None:
        rec = self._records.get(address)
        if rec is not None and now - rec.last_failure > self.forget_s:
            del self._records[address]
            return None
        return rec

    def blocked_for(self, address: str) -> float:
        """Seconds the address must still wait (0: it may try)."""
        now = self._clock()
        with self._lock:
            rec = self._record(address, now)
            return 0.0 if rec is None else max(0.0, rec.blocked_until - now)

    def failed(self, address: str, what: str) -> float:
        """Count a wrong credential; returns the delay [s] to hold the answer back."""
        now = self._clock()
        with self._lock:
            rec = self._record(address, now)
            if rec is None:
                if len(self._records) >= MAX_ADDRESSES:
                    self._records.clear()  # bounded memory; an attacker gains a fresh start at most
                rec = self._records[address] = _Record()
            rec.failures += 1
            rec.last_failure = now
            past = rec.failures - self.free_failures
            if past <= 0:
                return 0.0
            delay = min(self.max_s, self.base_s * 2 ** (past - 1))
            rec.blocked_until = now + 2 * delay  # held back ``delay``, then ``delay`` more before a new try
            n = rec.failures
        if past == 1 or (n & (n - 1)) == 0:
            log.warning("%d wrong %s from %s: throttled, answers delayed %.1f s", n, what, address, delay)
        return delay

    def succeeded(self, address: str) -> None:
        with self._lock:
            self._records.pop(address, None)
