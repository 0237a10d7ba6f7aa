"""Static blocks: outputs that are functions of the inputs at the same instant (direct feedthrough).

Each output is an algebraic unknown of the DAE (``blocks.base``)::

    Constant    y = k
    Gain        y = k u
    Sum         y = k1 u1 + k2 u2 + k3 u3         (u3 defaults to 0)
    Feedback    y = u1 - u2                        (reference minus measurement)
    Product     y = u1 u2
    Min / Max   y = min(u1, u2) / max(u1, u2)      kink at u1 = u2: a switching surface (event)
    Saturation  y = min(max(u, y_min), y_max)      kinks at the limits: switching surfaces (events)
    Switch      y = u1 if u2 > threshold else u3   jump at u2 = threshold: a switching surface (event); the
                                                   branch is a state set at restarts (``branch_states``)
    Compare     y = 1 if u > ref else 0            jump at u = ref: as Switch
    Table1D     y = table(u)                       linear between breakpoints, held beyond the ends; its
                                                   slope's kinks are left to the step-size control

Units: an output carries the unit of what it computes only where the block knows it (a sensor's); these
blocks pass values on in whatever unit their inputs have, and ``Compare`` gives 0/1.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import sympy

from ..component import Param, refuse_positional
from ..errors import ParameterError
from .base import Block, Input, clip


class Constant(Block):
    """``y = k``: a constant value as a block output."""

    outputs = {"y": ""}
    k = Param(check="real", doc="the value")

    def output_laws(self, e, de):
        return {"y": self.k}


class Gain(Block):
    """``y = k u``."""

    outputs = {"y": ""}
    u = Input(doc="input")
    k = Param(check="real", doc="gain")

    def output_laws(self, e, de):
        return {"y": self.k * self.u}


class Sum(Block):
    """``y = k1 u1 + k2 u2 + k3 u3`` (``u3`` 0 unless given)."""

    outputs = {"y": ""}
    u1 = Input(doc="first input")
    u2 = Input(doc="second input")
    u3 = Input(doc="third input", default=0.0)
    k1 = Param(1.0, check="real", doc="weight of u1")
    k2 = Param(1.0, check="real", doc="weight of u2")
    k3 = Param(1.0, check="real", doc="weight of u3")

    def output_laws(self, e, de):
        return {"y": self.k1 * self.u1 + self.k2 * self.u2 + self.k3 * self.u3}


class Feedback(Block):
    """``y = u1 - u2``: the error of a loop (``u1`` the reference, ``u2`` the measurement)."""

    outputs = {"y": ""}
    u1 = Input(doc="reference")
    u2 = Input(doc="measurement")

    def output_laws(self, e, de):
        return {"y": self.u1 - self.u2}


class Product(Block):
    """``y = u1 u2``."""

    outputs = {"y": ""}
    u1 = Input(doc="first factor")
    u2 = Input(doc="second factor")

    def output_laws(self, e, de):
        return {"y": self.u1 * self.u2}


class Min(Block):
    """``y = min(u1, u2)``; the change of branch at ``u1 = u2`` is an event."""

    outputs = {"y": ""}
    u1 = Input(doc="first input")
    u2 = Input(doc="second input")

    def output_laws(self, e, de):
        return {"y": sympy.Piecewise((self.u1, self.u1 < self.u2), (self.u2, True))}

    def switching_surfaces(self, e, de):
        return [(self.u1 - self.u2, 1)]


class Max(Block):
    """``y = max(u1, u2)``; the change of branch at ``u1 = u2`` is an event."""

    outputs = {"y": ""}
    u1 = Input(doc="first input")
    u2 = Input(doc="second input")

    def output_laws(self, e, de):
        return {"y": sympy.Piecewise((self.u1, self.u1 > self.u2), (self.u2, True))}

    def switching_surfaces(self, e, de):
        return [(self.u1 - self.u2, 1)]


class Saturation(Block):
    """``y = min(max(u, y_min), y_max)``; reaching or leaving a limit is an event (kind "limit")."""

    outputs = {"y": ""}
    u = Input(doc="input")
    y_min = Param(check="real", doc="lower limit")
    y_max = Param(check="real", doc="upper limit")

    def check_block(self):
        if not self.y_min < self.y_max:
            raise ParameterError(f"Saturation '{self.name}': needs y_min < y_max, got y_min={self.y_min}, "
                                 f"y_max={self.y_max}; swap them or widen the band")

    def output_laws(self, e, de):
        return {"y": clip(self.u, self.y_min, self.y_max)}

    def switching_surfaces(self, e, de):
        return [(self.u - self.y_max, 1), (self.y_min - self.u, -1)]


class Switch(Block):
    """``y = u1 if u2 > threshold else u3`` (MSL ``Switch`` with a threshold). The branch is the state ``q``
    (1 above the threshold, 0 below), set at every restart from the side of the surface ``u2 - threshold``
    (``Device.branch_states``): the crossing is an event, and no step meets the jump of ``y``."""

    outputs = {"y": ""}
    internal = {"q": None}
    branch_states = {"q": 0}
    switching_kind = "switch"
    u1 = Input(doc="value while u2 > threshold")
    u2 = Input(doc="control input")
    u3 = Input(doc="value while u2 <= threshold")
    threshold = Param(0.0, check="real", doc="switching level of u2")

    def output_laws(self, e, de):
        return {"y": self.q * self.u1 + (1 - self.q) * self.u3}

    def rates(self, e, de):
        return {"q": 0}

    def switching_surfaces(self, e, de):
        return [(self.u2 - self.threshold, 1)]


class Compare(Block):
    """``y = 1 if u > ref else 0``: the branch state ``q`` itself (as ``Switch``); the crossing is an event."""

    outputs = {"y": "1"}
    internal = {"q": None}
    branch_states = {"q": 0}
    switching_kind = "switch"
    u = Input(doc="input")
    ref = Input(doc="level", default=0.0)

    def output_laws(self, e, de):
        return {"y": self.q}

    def rates(self, e, de):
        return {"q": 0}

    def switching_surfaces(self, e, de):
        return [(self.u - self.ref, 1)]


def _table_points(name, table) -> np.ndarray:
    """The (n, 2) breakpoints of a ``Table1D``, checked (ParameterError naming the block and the fix)."""
    try:
        arr = np.array(table, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 2 or not np.all(np.isfinite(arr)):
        raise ParameterError(f"Table1D '{name}': table must be finite (x, y) pairs, at least two, got {table!r}")
    bad = np.nonzero(np.diff(arr[:, 0]) <= 0)[0]
    if len(bad):
        i = int(bad[0])
        raise ParameterError(
            f"Table1D '{name}': the breakpoints x must be strictly increasing, but x[{i + 1}]={arr[i + 1, 0]:g} "
            f"follows x[{i}]={arr[i, 0]:g}; sort the table by its first column and remove repeated x")
    arr.setflags(write=False)
    return arr


class Table1D(Block):
    """``y = table(u)``: linear interpolation in ``table`` ((n, 2) points, x strictly increasing), the end
    values held beyond the ends. The points are part of the law, so each distinct table is its own class
    (compiled once per table)."""

    outputs = {"y": ""}
    u = Input(doc="input (the table's x)")
    table = Param(check="any", doc="(n, 2) points (x, y), x strictly increasing")
    _points: ClassVar[np.ndarray | None] = None
    _public: ClassVar[type | None] = None
    _classes: ClassVar[dict] = {}

    def __new__(cls, name=None, *args, **params):
        public = cls._public or cls
        refuse_positional(public, (name, *args))
        points = _table_points(name, params.get("table"))
        key = points.tobytes() + bytes(str(points.shape), "ascii")
        sub = Table1D._classes.get(key)
        if sub is None:
            sub = type(public.__name__, (public,), {"_points": points, "_public": public,
                                                    "__module__": public.__module__,
                                                    "__qualname__": public.__qualname__, "__doc__": public.__doc__})
            Table1D._classes[key] = sub
        return object.__new__(sub)

    def __reduce_ex__(self, protocol):
        return _table_shell, (self.table,), self.__dict__

    def check_block(self):
        self._values["table"] = _table_points(self.name, self.table)

    def output_laws(self, e, de):
        pts = self._points          # (a class attribute: read through the compiler's stand-in too)
        u = self.u
        pieces = [(float(pts[0, 1]), u < float(pts[0, 0]))]
        for (x0, y0), (x1, y1) in zip(pts[:-1], pts[1:]):
            slope = (y1 - y0) / (x1 - x0)
            pieces.append((float(y0) + float(slope) * (u - float(x0)), u < float(x1)))
        pieces.append((float(pts[-1, 1]), True))
        return {"y": sympy.Piecewise(*pieces)}


def _table_shell(table):
    """Unpickling helper: an empty ``Table1D`` of the class of ``table``."""
    return Table1D.__new__(Table1D, "table", table=table)


__all__ = ["Constant", "Gain", "Sum", "Feedback", "Product", "Min", "Max", "Saturation", "Switch", "Compare",
           "Table1D"]
