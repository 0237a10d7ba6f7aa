"""The compiled right-hand side of the linear ODE form (``compile._odeform_kernels``) gives the
Python form's numbers to the last bit, on every kind of matrix it takes (DIA, CSR, compact and general
input matrices, constant offsets, device states), and is not taken where it could not."""

import math

import numpy as np
import pytest

import regmech as rm
from regmech.bench.hard_models import benchmark_chain
from regmech.compile import odeform
from regmech.components import DCMotor, Fixed, Inertia, LinearSpeedDependentTorque, SpringDamper, Torque
from regmech.signals import Ramp, Sine, Step

pytest.importorskip("numba")
from regmech.compile import _odeform_kernels as K  # noqa: E402  (numba)


def tree(branches: int, length: int, seed: int = 0) -> rm.Model:
    """A hub inertia with ``branches`` chains of ``length`` inertias (spring-dampers of random stiffness):
    no few diagonals hold its matrices (CSR). Each branch ends in a DC motor (voltage steps and sines: a
    state per motor and input signals), a torque or a speed-dependent load; the springs' rest angles are
    constant offsets."""
    rng = np.random.default_rng(seed)
    m = rm.Model(f"tree{branches}x{length}")
    fixed = m.add(Fixed("fixed"))
    hub = m.add(Inertia("hub", J=5.0))
    ground = m.add(SpringDamper("hub_ground", c=1e3, d=2.0))
    m.connect(hub.flange_b, ground.flange_a)
    m.connect(ground.flange_b, fixed.flange)
    for b in range(branches):
        prev = hub.flange_a if b == 0 else hub.flange_b
        for i in range(length):
            J = m.add(Inertia(f"J{b}_{i}", J=float(rng.uniform(0.5, 2.0)), w0=float(rng.normal())))
            sd = m.add(SpringDamper(f"sd{b}_{i}", c=float(10 ** rng.uniform(2, 5)), d=float(rng.uniform(0.1, 3)),
                                    phi_rel0=float(rng.uniform(-0.1, 0.1))))     # constant offsets (t0)
            m.connect(prev, sd.flange_a)
            m.connect(sd.flange_b, J.flange_a)
            prev = J.flange_b
        kind = b % 3
        if kind == 0:
            u = Step(height=float(rng.uniform(5, 20)), start_time=0.3 + 0.1 * b, offset=1.0) if b % 2 else \
                Sine(amplitude=12.0, freq_hz=float(rng.uniform(1, 8)), offset=24.0)
            mot = m.add(DCMotor(f"motor{b}", u=u, R=0.5, L=0.01, k=0.2))
            m.connect(mot.flange, prev)
        elif kind == 1:
            tq = m.add(Torque(f"torque{b}", tau=Sine(amplitude=3.0, freq_hz=2.0, offset=0.5, start_time=0.2)))
            m.connect(tq.flange, prev)
        else:
            load = m.add(LinearSpeedDependentTorque(f"load{b}", tau_nominal=4.0, w_nominal=10.0))
            m.connect(load.flange, prev)
    return m


def sines(count: int) -> rm.Model:
    """A chain of 100 inertias with a sine torque on every eighth: with the drive, ``count`` + 1 >= 8 sines of one class are
    evaluated by one numpy expression (``SignalBank``), whose sin need not round as the C library's does,
    so Python writes them for the kernel."""
    m = benchmark_chain(100)
    for k in range(count):
        tq = m.add(Torque(f"sine{k}", tau=Sine(amplitude=1.0 + k, freq_hz=0.7 + 1.3 * k, phase=0.1 * k,
                                                 start_time=0.05 * k, offset=0.01 * k)))
        m.connect(tq.flange, m[f"J{(8 * k) % 100}"].flange_b)
    return m


def forms(c, monkeypatch):
    """(compiled form, Python form) of one compiled system."""
    native = odeform.OdeForm(c)
    monkeypatch.setattr(odeform, "NATIVE", False)
    python = odeform.OdeForm(c)
    monkeypatch.setattr(odeform, "NATIVE", True)
    return native, python


@pytest.mark.parametrize("build", [
    lambda: benchmark_chain(300),
    lambda: benchmark_chain(120, tau=Step(height=7.0, start_time=0.5)),
    lambda: benchmark_chain(80, tau=lambda t: 3.0 * math.cos(7.0 * t)),
    lambda: benchmark_chain(90, tau=Ramp(height=4.0, duration=0.3, start_time=0.5, offset=-1.0)),
    lambda: tree(6, 12),
    lambda: tree(9, 20, seed=4),
    lambda: sines(12),
], ids=["chain300", "chain120_step", "chain80_callable", "chain90_ramp", "tree6x12", "tree9x20", "sines12"])
def test_compiled_linear_form_gives_the_python_form_to_the_last_bit(build, monkeypatch):
    c = build().compile()
    native, python = forms(c, monkeypatch)
    assert native.linear and native._native is not None and python._native is None
    rng = np.random.default_rng(7)
    c._t_right = 0.5
    times = [(0.0, None), (0.37, None), (0.5, True), (0.5, False), (0.8, True), (0.8, False), (1.9, None)]
    times += [(float(t), None) for t in rng.uniform(0.0, 2.0, 40)]
    for t, left in times:
        u = rng.normal(size=c.ode_size()) * 10.0 ** rng.integers(-3, 3)
        a, b = native.rhs(t, u, left), python.rhs(t, u, left)
        assert a.dtype == b.dtype and np.array_equal(a, b), (t, left)
        assert a is not native.rhs(t, u, left)          # a new array per call: scipy keeps the slopes


def test_the_kernel_evaluates_the_library_signals_and_python_the_others():
    on = lambda m: odeform.ode_form(m.compile())._native[3]
    assert on(benchmark_chain(300)) and on(tree(6, 12)) and on(sines(6))
    assert not on(benchmark_chain(80, tau=lambda t: 3.0 * math.cos(7.0 * t))) and not on(sines(7))


def test_tree_has_every_part_of_the_kernel():
    form = odeform.ode_form(tree(6, 12).compile())
    assert form.c.nz > 0 and not form.t0_zero and form.V is not None and form.v_rows is not None


def test_general_input_matrix_gives_the_python_form_to_the_last_bit(monkeypatch):
    # no library device puts two signal terms on one output row, so the compact V always applies there;
    # the general product (``out += V @ buf``) is taken by dropping the compact one on both forms
    c = tree(6, 12).compile()
    native, python = forms(c, monkeypatch)
    for form in (native, python):
        form.v_rows = None
    native._native = native._native_arguments()
    assert native._native[1][K.I_PLACES + 2 * K.I_PARTS.index("v_rows") + 1] == 0      # no compact V: general
    rng = np.random.default_rng(2)
    c._t_right = 0.5
    for t in (0.05, 0.42, 1.3):
        u = rng.normal(size=c.ode_size())
        assert np.array_equal(native.rhs(t, u), python.rhs(t, u)), t


def test_compiled_form_reads_non_contiguous_states(monkeypatch):
    c = tree(3, 25).compile()
    native, python = forms(c, monkeypatch)
    u = np.random.default_rng(1).normal(size=2 * c.ode_size())[::2]
    assert np.array_equal(native.rhs(0.2, u), python.rhs(0.2, u))


def test_tree_takes_the_row_ordered_form_and_the_chain_the_diagonal_one():
    # the two kinds of product the kernel has (a change in fast_operator would leave one of them untested)
    assert odeform.ode_form(tree(6, 12).compile())._native[1][K.H_TK] == K.CSR
    assert odeform.ode_form(benchmark_chain(300).compile())._native[1][K.H_TK] == K.DIA


def test_small_dense_form_keeps_the_python_path():
    # a dense matrix is multiplied by BLAS, whose order of the sums the kernel cannot repeat
    form = odeform.ode_form(benchmark_chain(5).compile())
    assert form.linear and form._native is None


def test_dop853_run_is_the_same_with_and_without_the_compiled_form(monkeypatch):
    m = tree(4, 15)
    sig = [f"J{b}_14.w" for b in range(4)] + ["motor0.i"]
    res = m.simulate(1.0, 0.01, solver="scipy:DOP853", rtol=1e-7)
    assert odeform.ode_form(m.compile())._native is not None
    monkeypatch.setattr(odeform, "NATIVE", False)
    m2 = tree(4, 15)
    res2 = m2.simulate(1.0, 0.01, solver="scipy:DOP853", rtol=1e-7)
    assert odeform.ode_form(m2.compile())._native is None
    for s in sig:
        assert np.array_equal(res[s], res2[s]), s
    assert res.stats.rhs_calls == res2.stats.rhs_calls and res.stats.steps == res2.stats.steps


def test_kernel_files_state_the_signal_formulas_they_were_written_against():
    # numba's cache of a kernel file is renewed only when that file changes: a new signal formula in
    # _native_signals must come with an edit of both kernel files, or their cached kernels keep the old one
    from regmech.compile._native_signals import source_hash
    from regmech.solvers import _native_kernels
    assert K.SIGNALS_SOURCE == source_hash() == _native_kernels.SIGNALS_SOURCE


@pytest.mark.parametrize("make", [lambda: benchmark_chain(300), lambda: tree(6, 12)], ids=["dia", "csr"])
def test_rhs_into_writes_the_same_numbers_as_rhs(make):
    # the Dormand-Prince integrators (solvers.dopri) have the kernel write each stage into their own rows
    form = odeform.ode_form(make().compile())
    assert form._native is not None
    rng = np.random.default_rng(3)
    for t in (0.0, 0.37, 1.2):
        u = rng.normal(size=form.size)
        out = np.full(form.size, np.nan)
        form.rhs_into(t, u, out)
        assert np.array_equal(out, form.rhs(t, u))


def test_compiled_jacobian_is_the_scipy_one():
    # the up-front stiffness check of the explicit methods assembles dg/du by one compiled pass when the form is
    # compiled (``OdeForm._compiled_jacobian``): the entries and the order of scipy's products, so the spectral
    # bound (and DOP853's step cap) is the same; checked against the scipy assembly on DIA and CSR forms
    cs = [benchmark_chain(n).compile() for n in (60, 300, 1000)]
    cs += [tree(b, n, seed=s).compile() for b, n, s in ((6, 12, 0), (10, 20, 3), (3, 40, 1), (20, 5, 2))]
    from regmech.solvers import ode_driver as od
    for c in cs:
        form = odeform.ode_form(c)
        assert form._native is not None and form.n_c
        form._A = None
        fast = form.jacobian()
        native, form._native, form._A = form._native, None, None
        try:
            slow = form.jacobian()
        finally:
            form._native, form._A = native, fast
        assert fast.shape == slow.shape and np.array_equal(fast.indptr, slow.indptr)
        assert abs(fast - slow).max() <= 1e-15 * abs(slow).max()
        assert od.spectral_bound(fast, c, compiled=True) == pytest.approx(od.spectral_bound(slow, c), rel=1e-14)
