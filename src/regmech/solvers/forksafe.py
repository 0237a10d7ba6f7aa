"""A lock that a child made by ``fork`` gets anew (``blas``, ``pages``).

A child made by ``fork`` while another thread held a ``threading.Lock`` inherits it held, with no thread to
release it: its first use there would wait forever. ``ForkSafeLock`` replaces its lock in the child
(``os.register_at_fork``; where there is no ``fork``, it is a plain lock). Meant for module-level locks: the
fork handler keeps the object alive for the life of the process.
"""

from __future__ import annotations

import os
import threading


class ForkSafeLock:
    """A ``threading.Lock`` (``with``, ``acquire``, ``release``) that is new and free in a forked child."""

    def __init__(self):
        self._lock = threading.Lock()
        if hasattr(os, "register_at_fork"):
            os.register_at_fork(after_in_child=self._renew)

    def _renew(self) -> None:
        self._lock = threading.Lock()

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        return self._lock.acquire(blocking, timeout)

    def release(self) -> None:
        self._lock.release()

    def __enter__(self):
        self._lock.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self._lock.release()


__all__ = ["ForkSafeLock"]
