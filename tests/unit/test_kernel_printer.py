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


def test_float_kernels_of_one_instance_match_the_numpy_kernels():
    """A class with one instance in a model evaluates its laws with Python floats (``Template.scalar``); on every
    template the library scenes and the fuzz families build, at random points (spread over decades, both signs,
    and at the parameters' own kinks), the float version and the numpy kernel agree to round-off, and where the
    float version cannot answer the group falls back to numpy."""
    import random

    from regmech.bench.fuzz import generate
    from regmech.compile import kernels as K

    for seed in range(40):
        spec = generate(random.Random(seed), name="kernels")
        spec.build().compile()
    rng = np.random.default_rng(0)
    checked = 0
    for tpl in list(K._TEMPLATES.values()):
        if tpl.exprs is None:
            continue
        for name, fn in (("res", tpl.res_fn), ("jac", tpl.jac_fn), ("surf", tpl.surf_fn)):
            sfn = tpl.scalar(fn) if fn is not None else None
            if sfn is None:
                continue
            nargs = len(tpl.exprs[name][0])
            for _ in range(30):
                vals = rng.standard_normal(nargs) * 10.0 ** rng.uniform(-3, 3, nargs)
                try:
                    got = sfn(*[float(v) for v in vals])
                except (ArithmeticError, ValueError, TypeError):
                    continue
                except NameError:       # a function the float printer does not know: the group uses numpy
                    break
                if None in got:
                    continue
                with np.errstate(all="ignore"):
                    want = fn(*[np.array([v]) for v in vals])
                for g, w in zip(got, want):
                    w = float(np.broadcast_to(np.asarray(w, float), (1,))[0])
                    if np.isfinite(w):
                        assert abs(g - w) <= 1e-9 * max(1.0, abs(w)), (tpl.cls.__name__, name, vals, g, w)
                checked += 1
    assert checked > 500
