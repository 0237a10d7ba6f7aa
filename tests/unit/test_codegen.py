"""Compiled class kernels (``compile.codegen``): each device class's symbolic law printed once as a numba C
callback. The compiled residual, Jacobian and switching surfaces equal the numpy ones of the same template for
every nonlinear class of the library's scenes; a user's subclass is compiled with no extra code; the printed
kernels are cached on disk across processes; a class that cannot be compiled stays on the Python path, named."""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest
import sympy

import regmech as rm
from regmech.components import Fixed, Inertia, Torque, TwoFlangeCompliant
from regmech.signals import Pulse, Table

pytest.importorskip("numba")
from regmech.compile import codegen  # noqa: E402
from regmech.solvers import ida_native  # noqa: E402

if isinstance(ida_native.libraries(), str):
    pytest.skip(f"native IDA not available: {ida_native.libraries()}", allow_module_level=True)

DOUBLE_P = ctypes.POINTER(ctypes.c_double)


def _call(cfunc, args, n, t, n_out):
    """The compiled callback on argument blocks ``args`` (each ``n`` values): its ``n_out`` outputs."""
    a = np.ascontiguousarray(np.concatenate([np.broadcast_to(x, (n,)) for x in args]) if args else np.zeros(1))
    out = np.full(max(n_out, 1) * n, np.nan)
    cfunc.ctypes(a.ctypes.data_as(DOUBLE_P), n, t, out.ctypes.data_as(DOUBLE_P))
    return out.reshape(max(n_out, 1), n)[:n_out]


def _numpy(fn, args, t, n, n_out):
    """The template's numpy function on the same arguments, as an ``(n_out, n)`` array."""
    out = fn(*args, t)
    return np.array([np.broadcast_to(np.asarray(o, float), (n,)) for o in out]).reshape(n_out, n)


def _scene_groups():
    """``(scene, group)`` for every nonlinear device class of the library's scenes (one group per class)."""
    from regmech.library import SCENES
    seen, out = set(), []
    for name, build in SCENES.items():
        c = build().compile()
        for g in c._plan.nonlinear:
            if g.tpl.cls not in seen and not g.tpl.reads:
                seen.add(g.tpl.cls)
                out.append(pytest.param(g, id=f"{name}-{g.tpl.cls.__name__}"))
    return out


@pytest.mark.parametrize("group", _scene_groups())
def test_compiled_law_equals_the_numpy_law_of_the_same_template(group):
    """At random arguments around the devices' own parameters: residual, Jacobian and surfaces to round-off."""
    tpl = group.tpl
    ker = codegen.class_kernels(tpl)
    assert not isinstance(ker, str), ker
    rng = np.random.default_rng(7)
    n = group.n
    for trial in range(5):
        scale = 10.0 ** rng.uniform(-2, 2)
        free = [scale * rng.uniform(-1, 1, n) for _ in range(2 * tpl.k + len(tpl.states))]
        inputs = [rng.uniform(-2, 2, n) for _ in tpl.inputs]
        args = free + [np.broadcast_to(np.asarray(p, float), (n,)) for p in group.param_values] + inputs
        t = float(rng.uniform(0, 5))
        for fn, cf, count in ((tpl.res_fn, ker.module.res, ker.n_res), (tpl.jac_fn, ker.jac and ker.module.jac,
                                                                          ker.n_jac),
                              (tpl.surf_fn, ker.surf and ker.module.surf, ker.n_surf)):
            if not count:
                continue
            want = _numpy(fn, args, t, n, count)
            got = _call(cf, args, n, t, count)
            finite = np.isfinite(want)
            assert np.array_equal(finite, np.isfinite(got)), (tpl.cls.__name__, want, got)
            np.testing.assert_allclose(got[finite], want[finite], rtol=1e-12,
                                       atol=1e-12 * max(1.0, float(np.abs(want[finite]).max(initial=0.0))))


def _spring_class(name, law):
    """A user's compliant class (the guide's way: a subclass with a symbolic ``law``)."""
    return type(name, (TwoFlangeCompliant,), {
        "__module__": __name__,
        "c": rm.Param(check="positive", unit="N m/rad", doc="stiffness"),
        "d": rm.Param(default=0.5, check="nonnegative", unit="N m s/rad", doc="damping"),
        "law": lambda self, rel, rel_dot: law(self, rel, rel_dot)})


def _oscillator(cls, tau=None):
    m = rm.Model(f"osc_{cls.__name__}")
    base = m.add(Fixed("base"))
    s = m.add(cls("s", c=100.0))
    J = m.add(Inertia("J", J=1.0, phi0=0.5, w0=0.0))
    m.connect(base.flange, s.flange_a)
    m.connect(s.flange_b, J.flange_a)
    if tau is not None:
        src = m.add(Torque("src", tau=tau))
        m.connect(src.flange, J.flange_b)
    return m


LAWS = {
    "cubic": lambda self, r, rd: self.c * r + 5e3 * r**3 + self.d * rd,
    "coulomb_sign": lambda self, r, rd: self.c * r + self.d * rd + 0.2 * sympy.sign(rd),
    "one_sided": lambda self, r, rd: self.c * r * (1 + sympy.Heaviside(r)) + self.d * rd,
    "stepped": lambda self, r, rd: self.c * r * (2 + sympy.floor(r)) + self.d * rd,
    "tanh_erf": lambda self, r, rd: self.c * sympy.tanh(r) + self.d * sympy.erf(3 * rd),
}


@pytest.mark.parametrize("law", sorted(LAWS))
def test_a_user_subclass_runs_compiled_with_the_python_path_s_answer(law):
    """No code beyond the law: the class is compiled, the run native, its answer the Python path's within the
    tolerance (jumps of ``sign``/``Heaviside``/``floor``: their derivative is zero between the jumps)."""
    m = _oscillator(_spring_class(f"Spring_{law}", LAWS[law]))
    native = m.simulate(2.0, dt_out=1e-2, solver="ida", rtol=1e-9, atol=1e-11, native=True)
    usual = m.simulate(2.0, dt_out=1e-2, solver="ida", rtol=1e-9, atol=1e-11, native=False)
    assert native.stats.extra["native"] is True
    np.testing.assert_array_equal(native.t, usual.t)
    for name in ("J.phi", "J.w"):
        scale = float(np.ptp(usual[name]))
        np.testing.assert_allclose(native[name], usual[name], rtol=0, atol=2e-4 * scale)


def test_a_law_with_a_function_regmech_cannot_evaluate_is_named():
    cls = _spring_class("LogIntegralSpring", lambda self, r, rd: self.c * sympy.li(2 + r * r))
    with pytest.raises(rm.ModelError, match=r"LogIntegralSpring 's'.*cannot evaluate.*li"):
        _oscillator(cls).simulate(0.1)


def test_a_special_function_numba_lacks_keeps_its_class_on_the_python_path_named():
    """scipy evaluates a Bessel function, the compiled kernels cannot: that class runs in Python, said once by a
    warning and in the run's stats, with the answer of the Python path."""
    cls = _spring_class("BesselSpring", lambda self, r, rd: self.c * sympy.besselj(1, r) + self.d * rd)
    m = _oscillator(cls)
    with pytest.warns(RuntimeWarning, match="BesselSpring: its law is not compiled"):
        res = m.simulate(1.0, dt_out=1e-2, solver="ida", rtol=1e-8, native=True)
    assert res.stats.extra["native"].startswith("not used: BesselSpring 's'")
    assert np.all(np.isfinite(res["J.w"])) and np.ptp(res["J.phi"]) > 0.1


def test_a_law_whose_derivative_sympy_cannot_form_is_named():
    cls = _spring_class("OpaqueSpring", lambda self, r, rd: self.c * sympy.Function("g")(r))
    with pytest.raises(rm.ModelError, match=r"OpaqueSpring 's'.*derivative of its law"):
        _oscillator(cls).simulate(0.1)


def test_a_class_that_cannot_be_compiled_stays_on_the_python_path_named(monkeypatch):
    """Where numba fails on a class, that class alone runs in Python: a warning once per class, the reason in
    the run's stats and in ``m.check()``, and the same answer."""
    def refuse(source):
        raise RuntimeError("numba refused the kernel")
    monkeypatch.setattr(codegen, "_load", refuse)
    cls = _spring_class("UncompiledSpring", LAWS["cubic"])
    m = _oscillator(cls)
    with pytest.warns(RuntimeWarning, match="UncompiledSpring: its law is not compiled.*numba refused"):
        res = m.simulate(1.0, dt_out=1e-2, solver="ida", rtol=1e-8, native=True)
    note = res.stats.extra["native"]
    assert note.startswith("not used: UncompiledSpring 's'") and "numba refused" in note
    assert "UncompiledSpring 's'" in m.check().solver_path
    plain = m.simulate(1.0, dt_out=1e-2, solver="ida", rtol=1e-8, native=False)
    np.testing.assert_array_equal(res["J.w"], plain["J.w"])


def test_check_says_which_path_ida_takes():
    from regmech.library import six_speed_car, slip_control
    assert six_speed_car().check().solver_path.startswith("ida with compiled callbacks")
    path = slip_control().check().solver_path
    assert path.startswith("ida with Python callbacks") and "Clutch 'clutch' reads inputs from the state" in path


@pytest.mark.parametrize("signal", [
    Table([(0.0, 0.0), (0.3, 2.0), (0.7, -1.0), (1.0, 0.5)]),
    Table([(0.0, 0.0), (0.3, 0.0), (0.3, 2.0), (0.7, 2.0), (0.7, -1.0)]),          # jumps: repeated times
    Pulse(amplitude=3.0, period=0.2, width=40.0, start_time=0.05, offset=-0.5),
], ids=["table_linear", "table_jumps", "pulse"])
def test_tables_and_pulses_drive_the_compiled_path_as_the_python_one(signal):
    m = _oscillator(_spring_class("DrivenSpring", LAWS["cubic"]), tau=signal)
    native = m.simulate(1.0, dt_out=1e-2, solver="ida", rtol=1e-9, atol=1e-11, native=True)
    usual = m.simulate(1.0, dt_out=1e-2, solver="ida", rtol=1e-9, atol=1e-11, native=False)
    assert native.stats.extra["native"] is True
    np.testing.assert_array_equal(native.t, usual.t)
    np.testing.assert_allclose(native["src.tau"], usual["src.tau"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(native["J.w"], usual["J.w"], rtol=0, atol=2e-4 * float(np.ptp(usual["J.w"])))


SCRIPT = textwrap.dedent("""
    import warnings
    import regmech as rm
    from regmech.components import Fixed, Inertia, TwoFlangeCompliant

    class CachedSpring(TwoFlangeCompliant):
        c = rm.Param(check="positive", unit="N m/rad")

        def law(self, rel, rel_dot):
            return self.c * rel + 40.0 * rel**3 + 0.3 * rel_dot

    m = rm.Model("cached")
    b = m.add(Fixed("b")); s = m.add(CachedSpring("s", c=50.0)); J = m.add(Inertia("J", J=1.0, phi0=0.2))
    m.connect(b.flange, s.flange_a); m.connect(s.flange_b, J.flange_a)
    res = m.simulate(0.5, dt_out=0.05, solver="ida", native=True, rtol=1e-6)
    assert res.stats.extra["native"] is True, res.stats.extra["native"]
    print(res["J.phi"][-1])
""")


@pytest.mark.slow
def test_kernels_are_cached_on_disk_and_reused_by_the_next_process(tmp_path):
    env = dict(os.environ, REGMECH_CACHE_DIR=str(tmp_path))
    first = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=600)
    assert first.returncode == 0, first.stderr[-3000:]
    folder = tmp_path / "kernels"
    files = {p.name: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}
    printed = [f for f in files if f.startswith("k_") and f.endswith(".py")]
    assert printed and any(f.endswith(".nbi") for f in files), files        # the source and numba's index
    second = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=600)
    assert second.returncode == 0, second.stderr[-3000:]
    assert second.stdout == first.stdout
    again = {p.name: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}
    assert again == files          # nothing printed or compiled again: the second process loaded the cache
