"""The kernels' numpy printer writes ``Piecewise`` as nested ``numpy.where`` (``compile.kernels._KernelPrinter``):
the same values as sympy's own evaluation, first true branch first, NaN where no branch holds."""

import numpy as np
import sympy

from regmech.compile.kernels import _lambdify


def test_piecewise_as_nested_where_matches_sympy():
    x, y = sympy.symbols("x y")
    exprs = [
        sympy.Piecewise((x ** 2, x < -1), (2 * x + y, x < 1), (y - x, True)),
        sympy.Piecewise((x, x > 0), (-x, y > 0)),                 # no default: NaN where neither holds
        sympy.Piecewise((1, (x > 0) & (y > 0)), (2, x > 0), (3, True)),
    ]
    fn = _lambdify([x, y], exprs)
    xs = np.array([-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 3.0])
    for yv in (-1.0, 2.0):
        got = fn(xs, np.full_like(xs, yv))
        for e, g in zip(exprs, got):
            want = np.array([float(e.subs({x: xv, y: yv})) if e.subs({x: xv, y: yv}) != sympy.nan
                             else np.nan for xv in xs])
            np.testing.assert_array_equal(np.broadcast_to(g, xs.shape), want)


def test_piecewise_printer_emits_no_select():
    x = sympy.symbols("x")
    fn = _lambdify([x], [sympy.Piecewise((x, x > 0), (0, True))])
    import inspect
    src = inspect.getsource(fn)
    assert "where" in src and "select" not in src
