"""Small sympy helpers shared by the component laws, written so that the kernels' numpy code never evaluates a
branch that divides by zero or needs an elementwise ``Min`` (numpy evaluates every branch of a ``Piecewise``).

``smaller(a, b)``: ``min(a, b)`` as arithmetic (contact surfaces of backlashes and stops).
``SpeedAbove(w, w_base)``: ``max(|w|, w_base)`` as one function (a power limit ``P / |w|`` above a base speed, an
inverse speed-dependent load).
"""

from __future__ import annotations

import sympy


def smaller(a, b):
    """``min(a, b)`` as arithmetic (the kernels' numpy printer has no elementwise Min)."""
    return (a + b - sympy.Abs(a - b)) / 2


class SpeedAbove(sympy.Function):
    """``SpeedAbove(w, w_base) = max(|w|, w_base)`` [rad/s] as one sympy function.

    Why not ``Max`` or ``Piecewise``: sympy folds ``1/Max(...)`` and its derivative into branches that
    hold ``1/|w|``, and numpy evaluates every branch, so the kernels would divide by zero at rest (a
    RuntimeWarning and an inf in the unused branch). This function prints as
    ``numpy.maximum(numpy.abs(w), w_base)`` and differentiates to ``sign(w) * Heaviside(|w| - w_base)``:
    finite everywhere, and ``1/SpeedAbove`` never divides by less than ``w_base > 0``."""

    @classmethod
    def eval(cls, w, w_base):
        if w.is_number and w_base.is_number:
            return sympy.Max(sympy.Abs(w), w_base)
        return None

    def fdiff(self, argindex=1):
        w, w_base = self.args
        step = sympy.Heaviside(sympy.Abs(w) - w_base, 0)
        return sympy.sign(w) * step if argindex == 1 else 1 - step

    def _numpycode(self, printer):
        w, w_base = (printer._print(a) for a in self.args)
        return f"numpy.maximum(numpy.abs({w}), {w_base})"

    def _pythoncode(self, printer):
        # the Python-float kernels of a class with one instance (``compile.kernels.Template.scalar``)
        w, w_base = (printer._print(a) for a in self.args)
        return f"max(abs({w}), {w_base})"


__all__ = ["SpeedAbove", "smaller"]
