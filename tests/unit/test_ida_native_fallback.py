"""Without numba (or with a SUNDIALS build the native path cannot read), ``native=True`` runs the usual IDA path
and says why; it never fails because the native path is missing."""

from __future__ import annotations

import numpy as np

from regmech.library import first
from regmech.solvers import ida_native


def test_native_without_its_libraries_runs_the_usual_path(monkeypatch):
    monkeypatch.setattr(ida_native, "_LIB", "numba is not installed (test); pip install 'regmech[native]'")
    m = first()
    res = m.simulate(0.3, dt_out=0.01, solver="ida", native=True)
    assert res.stats.extra["native"].startswith("not used: numba is not installed")
    plain = m.simulate(0.3, dt_out=0.01, solver="ida")
    np.testing.assert_array_equal(res["inertia3.w"], plain["inertia3.w"])
