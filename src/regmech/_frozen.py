"""Read-only tables of validated parameters.

A table a component has checked (a friction device's ``mu_table``, a lossy gear's ``loss_table``, an
engine's ``torque_map``, a ``Table`` signal's ``points``) is kept as a read-only copy: an in-place edit
would change a value behind the checks (and behind the compiled kernels, which keep their own copy).
numpy refuses such an edit with a bare ``ValueError: assignment destination is read-only`` that names
nothing; a ``FrozenTable`` refuses it with a ``ParameterError`` naming the component, the parameter and
the fix (assign a new table). Any computation with it gives a plain ``ndarray``; a copy is writeable.
"""

from __future__ import annotations

import numpy as np

from .errors import ParameterError


class FrozenTable(np.ndarray):
    """A read-only ``ndarray`` that names its owner when written to (module docstring)."""

    #: ``(owner, parameter)``: e.g. ``("Clutch 'clutch1'", "mu_table")``; None when unknown
    _owner = None

    def __array_finalize__(self, obj):
        self._owner = getattr(obj, "_owner", None)

    def _refuse(self):
        owner, name = self._owner or ("the component", "table")
        attr = name if name.isidentifier() else "table"
        raise ParameterError(
            f"{owner}: parameter '{name}' is read-only (it was validated when it was given, and an edit in place "
            f"would bypass the checks); assign a new table instead, e.g. t = comp.{attr}.copy(); t[1, 1] = 0.3; "
            f"comp.{attr} = t")

    def __setitem__(self, key, value):
        if not self.flags.writeable:
            self._refuse()
        super().__setitem__(key, value)

    def __array_ufunc__(self, ufunc, method, *inputs, out=None, **kwargs):
        # results are plain arrays; an in-place operation on a read-only table (``tab *= 2``) is refused by name
        if out is not None:
            for o in out:
                if isinstance(o, FrozenTable) and not o.flags.writeable:
                    o._refuse()
            kwargs["out"] = tuple(o.view(np.ndarray) if isinstance(o, FrozenTable) else o for o in out)
        inputs = tuple(x.view(np.ndarray) if isinstance(x, FrozenTable) else x for x in inputs)
        return getattr(ufunc, method)(*inputs, **kwargs)

    def __reduce__(self):
        return (frozen, (np.asarray(self).copy(), *(self._owner or (None, None))))


def frozen(value, owner: str | None = None, name: str | None = None) -> FrozenTable:
    """A read-only float copy of ``value``; ``owner`` (``"Clutch 'c1'"``) and ``name`` (the parameter) are named
    when something tries to write to it."""
    arr = np.array(value, dtype=float).view(FrozenTable)
    if owner is not None:
        arr._owner = (owner, name or "table")
    arr.setflags(write=False)
    return arr
