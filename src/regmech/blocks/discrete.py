"""Sampled blocks: an ECU's task rate.

``SampleHold``: ``y(t) = u(t_k)`` for ``t_k <= t < t_k + T``, ``t_k = t0 + k T`` (k = 0, 1, ...); before
``t0`` it holds ``y0``. ``y`` is a state of rate 0 (``Device.sampled_states``); every sample instant is a
time event of the run (the block's ``clock`` signal declares them as breakpoints), at which the solver stops
and restarts with ``y`` set to the input's value there (``compile.reads.settle``). ``T`` [s] > 0.
"""

from __future__ import annotations

import math
import sys

from ..component import Param
from ..errors import ParameterError
from ..signals import Signal
from .base import Block, Input


class SampleClock(Signal):
    """Zero, with breakpoints at ``t0 + k T`` (k >= 0): the sample instants of a ``SampleHold``."""

    def __init__(self, period: float, t0: float):
        self.period, self.t0 = float(period), float(t0)

    def value(self, t, left=False):
        return 0.0

    def derivative(self, t, order=1, left=False):
        return 0.0

    def _k_range(self, t_start, t_end):
        lo = max(0, math.ceil((t_start - self.t0) / self.period))
        hi = math.floor((t_end - self.t0) / self.period)
        return lo, hi

    def breakpoints(self, t_start=-math.inf, t_end=math.inf):
        if not math.isfinite(t_end):
            raise ParameterError("SampleClock.breakpoints needs a finite time range")
        lo, hi = self._k_range(t_start if math.isfinite(t_start) else self.t0, t_end)
        return tuple(self.t0 + k * self.period for k in range(lo, hi + 1))

    def count_breakpoints(self, t_start, t_end):
        if not (math.isfinite(t_start) and math.isfinite(t_end)):
            return sys.maxsize
        lo, hi = self._k_range(t_start, t_end)
        return max(0, hi - lo + 1)

    def bounds(self):
        return (0.0, 0.0)


class SampleHold(Block):
    """Sample-and-hold at period ``T`` (module docstring)."""

    dynamic_outputs = {"y": "y0"}
    sampled_states = {"y": ("u", "T", "t0")}
    u = Input(doc="input, sampled")
    T = Param(check="real", unit="s", doc="sample period > 0")
    t0 = Param(0.0, check="real", unit="s", doc="first sample instant")
    y0 = Param(0.0, check="real", doc="output before the first sample")
    clock = Param(None, check="any", optional=True, doc="(set by the block) the sample instants as a signal")

    def check_block(self):
        if not self.T > 0:
            raise ParameterError(f"SampleHold '{self.name}': the sample period T must be > 0 s, got T={self.T:g}; "
                                 f"give the task rate's period, e.g. T=0.01 for 100 Hz")
        self._values["clock"] = SampleClock(self.T, self.t0)

    def rates(self, e, de):
        return {"y": 0}


__all__ = ["SampleHold", "SampleClock"]
