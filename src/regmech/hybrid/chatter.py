"""The chatter guard: a run stops when the mode logic cannot settle a device."""

from __future__ import annotations

from collections import deque

from ..errors import ChatteringError


class ChatterGuard:
    """Stops a run when one device changes mode ``count`` times within ``window`` seconds.

    Every solver records each mode change here (``record``); a device that keeps switching
    (stuck -> sliding -> stuck ...) faster than that is chattering: the stick/slip logic cannot
    settle it, and the run would otherwise crawl on at the event rate.
    """

    def __init__(self, window: float, count: int):
        self.window, self.count = window, count
        self.log: dict[str, deque[float]] = {}

    def record(self, t: float, name: str) -> None:
        times = self.log.setdefault(name, deque())
        times.append(t)
        while times and times[0] < t - self.window:
            times.popleft()
        if len(times) >= self.count:
            raise ChatteringError(
                f"friction device '{name}' changed mode {len(times)} times within {self.window:g} s before "
                f"t={t:.9g} (chattering): the stick/slip logic cannot settle. Remedies: add damping or compliance "
                f"next to it (an elastic shaft), use peak > 1 (static above kinetic friction), or give the masses "
                f"on both sides realistic inertia.")
