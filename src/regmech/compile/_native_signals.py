"""The signals that compiled code evaluates itself (numba; imported only when numba is installed).

Shared by the native IDA kernels (``solvers._native_kernels``) and the compiled right-hand side of the
linear ODE form (``compile._odeform_kernels``). ``signal_value`` repeats the formulas of
``regmech.signals`` in the same order of operations (``math.sin`` is the C library's ``sin`` on both
sides), so a signal gives the same number compiled or not. Signals of other classes (tables, user
functions, subclasses) keep their Python path.

numba's on-disk cache of a kernel is invalidated by a change of the kernel's own file only, not of this one,
whose ``signal_value`` is compiled into the kernels of ``compile._odeform_kernels`` and
``solvers._native_kernels``. Each of those files therefore states ``SIGNALS_SOURCE``, the ``source_hash`` of
``signal_value`` it was written against, and a test compares them: editing ``signal_value`` fails that test
until both files are edited too, which renews their caches.
"""

from __future__ import annotations

import hashlib
import inspect
import math

import numpy as np
from numba import njit

#: signal kinds
CONSTANT, SINE, STEP, RAMP = 0, 1, 2, 3
#: parameters per signal
N_PAR = 5
#: signal classes the kernels evaluate
SUPPORTED = ("Constant", "Sine", "Step", "Ramp")


@njit(cache=True, inline="always")
def signal_value(kind, p, t, left):
    """A signal's value at t, left limit when ``left``: the formulas of ``regmech.signals``."""
    if kind == SINE:             # p = offset, amplitude, freq_hz, phase, start_time
        on = t > p[4] if left else t >= p[4]
        if not on:
            return p[0]
        return p[0] + p[1] * math.sin(2.0 * math.pi * p[2] * (t - p[4]) + p[3])
    if kind == STEP:             # p = offset, height, start_time
        on = t > p[2] if left else t >= p[2]
        return p[0] + (p[1] if on else 0.0)
    if kind == RAMP:             # p = offset, height, duration, start_time
        t0 = p[3]
        if t < t0 or (left and t == t0):
            return p[0]
        if t >= t0 + p[2]:
            return p[0] + p[1]
        return p[0] + p[1] * (t - t0) / p[2]
    return p[0]                  # CONSTANT


def signal_entry(s):
    """(kind, parameters) of a signal the kernels evaluate, or None."""
    name = type(s).__name__
    if name not in SUPPORTED or type(s).__module__ != "regmech.signals":
        return None
    p = np.zeros(N_PAR)
    if name == "Sine":
        p[:5] = s.offset, s.amplitude, s.freq_hz, s.phase, s.start_time
        return SINE, p
    if name == "Step":
        p[:3] = s.offset, s.height, s.start_time
        return STEP, p
    if name == "Ramp":
        p[:4] = s.offset, s.height, s.duration, s.start_time
        return RAMP, p
    p[0] = s.value_
    return CONSTANT, p


def signal_table(plan):
    """(kinds, slots, parameters) of every signal in the input slots of ``plan``
    (``EvaluationPlan.input_slots``: the value of signal i of bank j of a group at ``start + j n + i``), or
    a string naming the first one the kernels cannot evaluate. Kept with the plan (read-only arrays): the
    library's signals are fixed when made (``regmech.signals.Signal``), and a new one recompiles the model."""
    kept = plan.__dict__.get("_native_signal_table")
    if kept is None:
        kept = plan._native_signal_table = _signal_table(plan)
    return kept


def _signal_table(plan):
    """``signal_table`` computed."""
    kinds, slots, pars = [], [], []
    for g, start, _, _ in plan.input_slots:
        for j, sigs in enumerate(g.signals):
            for i, s in enumerate(sigs):
                entry = signal_entry(s)
                if entry is None:
                    return (f"{type(g.devices[i]).__name__} '{g.devices[i].name}' has a {type(s).__name__} signal "
                            f"(the native path evaluates {', '.join(SUPPORTED)})")
                kinds.append(entry[0])
                slots.append(start + j * g.n + i)
                pars.append(entry[1])
    table = (np.array(kinds, np.int64), np.array(slots, np.int64), np.concatenate(pars) if pars else np.zeros(0))
    for a in table:
        a.flags.writeable = False       # shared by the native IDA layouts and the ODE form
    return table


def source_hash() -> str:
    """The first 16 hex digits of the SHA-256 of ``signal_value``'s source (module docstring)."""
    return hashlib.sha256(inspect.getsource(signal_value.py_func).encode()).hexdigest()[:16]
