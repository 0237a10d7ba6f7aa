"""What counts as a number wherever regmech takes one (solver options, times, parameters).

Any real scalar is accepted, whatever its type: ``int``, ``float``,
numpy scalars (``np.float32``, ``np.int64``, ...), 0-d real arrays and
other ``numbers.Real`` types (``Fraction``). ``bool`` is refused: ``True``
where a tolerance or a step is expected is a mistake, not the number 1.
"""

from __future__ import annotations

import math
import numbers

import numpy as np


def as_real(value) -> float | None:
    """``value`` as a Python float when it is a real scalar (see module docstring); None otherwise."""
    if isinstance(value, (bool, np.bool_)):
        return None
    if isinstance(value, np.ndarray):
        if value.ndim != 0 or value.dtype.kind not in "iuf":
            return None
        value = value[()]
    if not isinstance(value, numbers.Real):
        return None
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return None


def as_integer(value) -> int | None:
    """``value`` as a Python int when it is a whole real scalar (``5``, ``np.int64(5)``, ``1e5``); None otherwise."""
    if isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return int(value)
    x = as_real(value)
    if x is None or not math.isfinite(x) or x != math.floor(x):
        return None
    return int(x)


def describe(value) -> str:
    """``repr`` of a refused value, shortened, with its type when the repr does not show it."""
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    if isinstance(value, (str, bytes)) or (as_real(value) is None and not isinstance(value, (bool, np.bool_))
                                           and value is not None and not text.startswith(type(value).__name__)):
        text += f" (a {type(value).__name__})"
    return text


def abs_max(arr) -> float:
    """``max |arr|`` of a 1-d float array as a Python float, 0 for an empty one, NaN when it holds a NaN (as
    numpy's reduction): in Python for a short array, where numpy's reduction costs more than the work (the
    solvers' and the mode logic's per-segment and per-event checks on small models); the same value either
    way."""
    if len(arr) <= 32:
        vals = arr.tolist()
        if any(map(math.isnan, vals)):
            return math.nan         # Python's max would keep or drop a NaN by where it stands
        return max(map(abs, vals), default=0.0)
    return float(np.abs(arr).max(initial=0.0))
