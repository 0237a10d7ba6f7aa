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
CONSTANT, SINE, STEP, RAMP, PULSE, TABLE = 0, 1, 2, 3, 4, 5
#: ``kind + DERIVED * order``: that signal's derivative of order 1 or 2 (``signal_slope``)
DERIVED = 8
#: parameters per signal
N_PAR = 5
#: signal classes every compiled kernel evaluates (``signal_value``)
SUPPORTED = ("Constant", "Sine", "Step", "Ramp", "Pulse")
#: ... and those the native IDA kernels evaluate from a pool of points beside the parameters (``signal_at``)
SUPPORTED_POOLED = SUPPORTED + ("Table",)


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
    if kind == PULSE:            # p = offset, amplitude, width [%], period, start_time
        if t < p[4] or (left and t == p[4]):
            return p[0]
        on_time = p[2] / 100.0 * p[3]
        k = math.floor((t - p[4]) / p[3])
        for kk in (k - 1, k, k + 1):
            t0 = p[4] + kk * p[3]
            if kk >= 0 and ((t0 < t <= t0 + on_time) if left else (t0 <= t < t0 + on_time)):
                return p[0] + p[1]
        return p[0]
    return p[0]                  # CONSTANT


@njit(cache=True, inline="always")
def table_piece(arr, base, n, t, left):
    """The piece ``k`` of a table's ``n`` times at ``arr[base:base + n]`` that holds ``t``: ``k + 1`` times are
    ``< t`` (left limits) or ``<= t``; -1 before the first, ``n - 1`` after the last."""
    lo, hi = 0, n
    while lo < hi:
        mid = (lo + hi) // 2
        tm = arr[base + mid]
        if tm < t or (not left and tm == t):
            lo = mid + 1
        else:
            hi = mid
    return lo - 1


@njit(cache=True, inline="always")
def table_value(arr, base, n, t, left):
    """``Table.value``: the ``n`` times at ``arr[base:base + n]``, the values after them; piece k holds
    ``[t_k, t_{k+1})`` (left limits ``(t_k, t_{k+1}]``), constant outside, a repeated time a jump."""
    k = table_piece(arr, base, n, t, left)
    v = base + n
    if k < 0:
        return arr[v]
    if k >= n - 1:
        return arr[v + n - 1]
    t0, t1 = arr[base + k], arr[base + k + 1]
    if t1 == t0:
        return arr[v + k + 1]
    return arr[v + k] + (arr[v + k + 1] - arr[v + k]) * (t - t0) / (t1 - t0)


@njit(cache=True, inline="always")
def signal_slope(kind, arr, off, t, left, order):
    """``Signal.derivative(t, order, left)`` of the signal of ``signal_at`` (order 1 or 2; the library's
    formulas): zero for Constant, Step and Pulse, the slope of a rising Ramp or of a Table's piece, the
    Sine's derivative once it is on."""
    if kind == SINE:
        p = arr[off:off + N_PAR]
        on = t > p[4] if left else t >= p[4]
        if not on:
            return 0.0
        w = 2.0 * math.pi * p[2]
        return p[1] * w ** order * math.sin(w * (t - p[4]) + p[3] + order * math.pi / 2.0)
    if order != 1:
        return 0.0
    if kind == RAMP:
        p = arr[off:off + N_PAR]
        t0, t1 = p[3], p[3] + p[2]
        rising = (t0 < t <= t1) if left else (t0 <= t < t1)
        return p[1] / p[2] if (p[2] > 0.0 and rising) else 0.0
    if kind == TABLE:
        base, n = int(arr[off]), int(arr[off + 1])
        k = table_piece(arr, base, n, t, left)
        if k < 0 or k >= n - 1 or arr[base + k + 1] == arr[base + k]:
            return 0.0
        return (arr[base + n + k + 1] - arr[base + n + k]) / (arr[base + k + 1] - arr[base + k])
    return 0.0


@njit(cache=True, inline="always")
def signal_at(kind, arr, off, t, left):
    """The value of the signal whose parameters sit at ``arr[off:off + N_PAR]``; a ``TABLE``'s are the index of
    its points in ``arr`` and their count (``pooled_entries``). A kind ``k + DERIVED * order`` is the signal of
    kind ``k``'s derivative of that order (``signal_slope``: a Position or Speed source's reference)."""
    if kind >= DERIVED:
        return signal_slope(kind % DERIVED, arr, off, t, left, kind // DERIVED)
    if kind == TABLE:
        return table_value(arr, int(arr[off]), int(arr[off + 1]), t, left)
    return signal_value(kind, arr[off:off + N_PAR], t, left)


def signal_entry(s, pooled=False):
    """(kind, parameters) of a signal the kernels evaluate, or None. With ``pooled`` a ``Table`` too: its
    parameters are ``[-1, n]`` and its points (times, then values) a third item, placed by
    ``pooled_entries``."""
    name = type(s).__name__
    if name not in (SUPPORTED_POOLED if pooled else SUPPORTED) or type(s).__module__ != "regmech.signals":
        return None
    p = np.zeros(N_PAR)
    if name == "Table":
        p[:2] = -1.0, len(s.points)
        return TABLE, p, np.concatenate([s.points[:, 0], s.points[:, 1]])
    if name == "Pulse":
        p[:5] = s.offset, s.amplitude, s.width, s.period, s.start_time
        return PULSE, p
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


def signal_table(plan, pooled=False):
    """(kinds, slots, parameters) of every signal in the input slots of ``plan``
    (``EvaluationPlan.input_slots``: the value of signal i of bank j of a group at ``start + j n + i``), or
    a string naming the first one the kernels cannot evaluate. With ``pooled`` (the native IDA kernels) tables
    too, as a fourth item: their points, to be placed after the parameters (``pooled_entries``; a table's first
    parameter is then relative to the parameters' start). Kept with the plan (read-only arrays): the
    library's signals are fixed when made (``regmech.signals.Signal``), and a new one recompiles the model."""
    key = "_native_signal_table_pooled" if pooled else "_native_signal_table"
    kept = plan.__dict__.get(key)
    if kept is None:
        kept = _signal_table(plan, pooled)
        setattr(plan, key, kept)
    return kept


def _signal_table(plan, pooled):
    """``signal_table`` computed."""
    entries, slots = [], []
    for g, start, _, _ in plan.input_slots:
        for j, sigs in enumerate(g.signals):
            for i, s in enumerate(sigs):
                entry = signal_entry(s, pooled)
                if entry is None:
                    names = SUPPORTED_POOLED if pooled else SUPPORTED
                    return (f"{type(g.devices[i]).__name__} '{g.devices[i].name}' has a {type(s).__name__} signal "
                            f"(the compiled kernels evaluate {', '.join(names)})")
                entries.append(entry)
                slots.append(start + j * g.n + i)
    if pooled:
        # Position and Speed sources: the reference and its derivatives at their slots (``EvaluationPlan``)
        for refs, orders in ((plan.pos_refs, 3), (plan.spd_refs, 2)):
            for slot, s in refs:
                for order in range(orders):
                    entry = derived_entry(s, order)
                    if entry is None:
                        return (f"a Position/Speed source has a {type(s).__name__} reference (the compiled "
                                f"kernels evaluate {', '.join(SUPPORTED_POOLED)})")
                    entries.append(entry)
                    slots.append(slot + order)
    kinds, pars, pool = pooled_entries(entries, 0)
    table = (kinds, np.array(slots, np.int64), pars) + ((pool,) if pooled else ())
    for a in table:
        a.flags.writeable = False       # shared by the native IDA layouts and the ODE form
    return table


def derived_entry(s, order):
    """``signal_entry(s, pooled=True)`` of the derivative of ``s`` of ``order`` (0: the signal itself), or None."""
    entry = signal_entry(s, pooled=True)
    if entry is None or order == 0:
        return entry
    return (entry[0] + DERIVED * order,) + tuple(entry[1:])


def pooled_entries(entries, base):
    """``(kinds, parameters, pool)`` of ``signal_entry(..., pooled=True)`` results placed in an array whose
    parameters start at ``base`` and whose pool follows them: each table's first parameter becomes the index
    of its points."""
    kinds = np.array([e[0] for e in entries], np.int64)
    pars = np.concatenate([e[1] for e in entries]) if entries else np.zeros(0)
    pool, pos = [], base + len(pars)
    for i, e in enumerate(entries):
        if e[0] % DERIVED == TABLE:
            pars[N_PAR * i] = pos
            pool.append(e[2])
            pos += len(e[2])
    return kinds, pars, (np.concatenate(pool) if pool else np.zeros(0))


def source_hash() -> str:
    """The first 16 hex digits of the SHA-256 of the source of the compiled signal formulas (module
    docstring)."""
    text = "".join(inspect.getsource(f.py_func) for f in (signal_value, table_piece, table_value, signal_slope, signal_at))
    return hashlib.sha256(text.encode()).hexdigest()[:16]
