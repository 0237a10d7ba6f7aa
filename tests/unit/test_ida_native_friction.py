"""The native IDA path on friction models (``solvers.ida_native``: friction rows, event functions and root
finding in numba kernels, the mode logic of ``hybrid`` at the events) against the scikit-sundae path on
the same models: the same path through the modes, switch times and signals within the tolerance of each
other and of an accurate reference; devices it cannot evaluate run the usual path and say why."""

from __future__ import annotations

import numpy as np
import pytest

import regmech as rm
from regmech.bench import hard_models as H
from regmech.components import (Brake, Clutch, Fixed, Force, FrictionContact, Inertia, Mass, SpringDamper,
                                Torque)
from regmech.library import coupled_clutches, gear_shift
from regmech.components.laws import Stribeck
from regmech.signals import Ramp, Sine, Step
from regmech.solvers.accuracy import net_changes

pytest.importorskip("numba")
from regmech.solvers import ida_native  # noqa: E402

if isinstance(ida_native.libraries(), str):
    pytest.skip(f"native IDA not available: {ida_native.libraries()}", allow_module_level=True)


def brake_and_clutch():
    """A spring-coupled pair with a brake (Ramp normal force) and a clutch (Sine, disengaging) on it, driven
    by a sine: stick, slip both ways and free modes, 17 events in 3 s."""
    m = rm.Model("brake_and_clutch")
    f = m.add(Fixed("fixed"))
    J1, J2, J3 = m.add(Inertia("J1", J=0.5, w0=3.0)), m.add(Inertia("J2", J=1.5)), m.add(Inertia("J3", J=0.8))
    sd = m.add(SpringDamper("sd", c=200.0, d=0.5))
    b = m.add(Brake("brake", mu=0.4, peak=1.3, fn_max=30.0,
                    f_normalized=Ramp(height=1.0, duration=0.5, start_time=0.1)))
    c = m.add(Clutch("clutch", mu=0.3, peak=1.2, fn_max=40.0, f_normalized=Sine(amplitude=1.0, freq_hz=0.7, phase=0.5)))
    tq = m.add(Torque("drive", tau=Sine(amplitude=12.0, freq_hz=1.3)))
    m.connect(tq.flange, J1.flange_a)
    m.connect(tq.support, f.flange)
    m.connect(J1.flange_b, sd.flange_a)
    m.connect(sd.flange_b, J2.flange_a)
    m.connect(J2.flange_b, b.flange)
    m.connect(b.support, f.flange)
    m.connect(J2.flange_b, c.flange_a)
    m.connect(c.flange_b, J3.flange_a)
    return m


def sliding_blocks():
    """Translational: two masses on a spring, the second on the ground through a FrictionContact whose normal
    force steps up; a sine force on the first."""
    m = rm.Model("sliding_blocks")
    f = m.add(Fixed("fixed", domain="translational"))
    m1, m2 = m.add(Mass("m1", m=2.0, v0=1.0)), m.add(Mass("m2", m=1.0))
    k = m.add(SpringDamper("k", c=500.0, d=1.0, domain="translational"))
    fc = m.add(FrictionContact("ground", mu=0.5, peak=1.2, fn=Step(height=10.0, start_time=0.3, offset=5.0)))
    push = m.add(Force("push", f=Sine(amplitude=8.0, freq_hz=1.0)))
    m.connect(push.flange, m1.flange_a)
    m.connect(push.support, f.flange)
    m.connect(m1.flange_b, k.flange_a)
    m.connect(k.flange_b, m2.flange_a)
    m.connect(m2.flange_b, fc.flange_a)
    m.connect(fc.flange_b, f.flange)
    return m


def friction_chain(n=40):
    """Inertias on spring-dampers with a clutch every tenth link (engaged by Steps) and a brake at the end:
    85 unknowns, IDA's band solver on a reordering (the friction rows in the solver's order)."""
    m = rm.Model("friction_chain")
    f = m.add(Fixed("fixed"))
    J = [m.add(Inertia(f"J{i}", J=1.0 + 0.1 * (i % 3), w0=2.0 if i == 0 else 0.0)) for i in range(n)]
    tq = m.add(Torque("drive", tau=Sine(amplitude=20.0, freq_hz=2.0)))
    m.connect(tq.flange, J[0].flange_a)
    m.connect(tq.support, f.flange)
    for i in range(n - 1):
        if i % 10 == 5:
            d = m.add(Clutch(f"c{i}", mu=0.4, peak=1.2, fn_max=30.0,
                             f_normalized=Step(height=1.0, start_time=0.1 * (i // 10 + 1))))
        else:
            d = m.add(SpringDamper(f"s{i}", c=2e3, d=2.0))
        m.connect(J[i].flange_b, d.flange_a)
        m.connect(d.flange_b, J[i + 1].flange_a)
    b = m.add(Brake("brake", mu=0.5, peak=1.3, fn_max=10.0, f_normalized=Step(height=1.0, start_time=0.5)))
    m.connect(J[-1].flange_b, b.flange)
    m.connect(b.support, f.flange)
    return m


def _first(x):
    return x[0] if isinstance(x, tuple) else x


SCENES = {
    "coupled_clutches": (coupled_clutches, 1.5),
    "brake_and_clutch": (brake_and_clutch, 3.0),
    "sliding_blocks": (sliding_blocks, 3.0),
    "simultaneous_lock": (lambda: _first(H.simultaneous_lock()), 3.0),
    "zero_speed_engagement": (lambda: _first(H.zero_speed_engagement()), 1.0),
    "gear_shift": (gear_shift, 2.0),
    "friction_chain_band": (friction_chain, 1.5),
}


def _path(res):
    """The mode changes device by device, those of one device at one instant merged (a clutch engaging at
    zero slip goes Free -> Forward -> Stuck or Free -> Backward -> Stuck by the round-off sign of its slip:
    both are Free -> Stuck), as the accuracy contract compares runs (``accuracy.net_changes``)."""
    return [(comp, old, new) for _, comp, old, new, _ in net_changes(res.events)]


def _state_names(res):
    return [n for n in res.names if n.endswith((".w", ".phi", ".v", ".s")) and "." in n and n.count(".") == 1]


def _pair(m, t_end, rtol):
    a = m.simulate(t_end, dt_out=1e-2, solver="ida", rtol=rtol, native=True)
    b = m.simulate(t_end, dt_out=1e-2, solver="ida", rtol=rtol, native=False)
    assert a.stats.extra.get("native") is True, a.stats.extra.get("native")
    assert "native" not in b.stats.extra
    return a, b


@pytest.mark.parametrize("key", sorted(SCENES))
def test_native_friction_runs_take_the_same_path_as_the_usual_path(key):
    build, t_end = SCENES[key]
    rtol = 1e-8
    a, b = _pair(build(), t_end, rtol)
    assert _path(a) == _path(b)
    assert a.stats.segments == b.stats.segments
    ta, tb = (np.array([e[0] for e in net_changes(r.events)]) for r in (a, b))
    # switch times: both located by IDA's root finding on the same functions at the same tolerance
    assert np.all(np.abs(ta - tb) <= 1e3 * rtol * max(1.0, t_end)), np.abs(ta - tb).max(initial=0.0)
    for name in _state_names(b):
        ya = np.interp(b.t, a.t, a[name])
        scale = max(1e-9, float(np.ptp(b[name])))
        assert float(np.abs(ya - b[name]).max()) <= 1e-5 * scale, name


@pytest.mark.parametrize("rtol", [1e-6, 1e-9])
def test_native_coupled_clutches_is_as_accurate_as_the_usual_path(rtol):
    m = coupled_clutches()
    ref = m.simulate(1.5, dt_out=1e-3, solver="scipy:DOP853", rtol=1e-12, atol=1e-14)
    a = m.simulate(1.5, dt_out=1e-3, solver="ida", rtol=rtol, native=True)
    b = m.simulate(1.5, dt_out=1e-3, solver="ida", rtol=rtol)
    assert a.stats.extra["native"] is True
    assert _path(a) == _path(b) == _path(ref)
    tg = np.linspace(0.0, 1.5, 1501)
    scale = max(float(np.ptp(ref[f"J{i}.w"])) for i in range(1, 5))

    def error(res):
        return max(float(np.abs(np.interp(tg, res.t, res[f"J{i}.w"]) - np.interp(tg, ref.t, ref[f"J{i}.w"])).max())
                   for i in range(1, 5)) / scale
    # the same method at the same tolerance: errors of the same size
    assert error(a) <= max(3.0 * error(b), 10.0 * rtol), (error(a), error(b))


@pytest.mark.parametrize("key, accuracy", [("coupled_clutches", 1e-3), ("coupled_clutches", 1e-6),
                                           ("brake_and_clutch", 1e-4), ("sliding_blocks", 1e-5)])
def test_solver_auto_runs_friction_models_natively_and_keeps_the_contract(key, accuracy):
    """The default call runs the native path; its answer is within the accuracy of a tight reference (the
    state signals, relative to the range of their kind, as the contract measures them) and takes the path
    through the modes that the Python callbacks take."""
    build, t_end = SCENES[key]
    m = build()
    res = m.simulate(t_end, dt_out=1e-2, accuracy=accuracy)
    assert res.stats.solver == "ida" and res.stats.extra["native"] is True
    assert res.stats.error_estimate <= accuracy
    ref = m.simulate(t_end, dt_out=1e-2, solver="ida", rtol=1e-11, atol=1e-13, native=False)
    assert _path(res) == _path(ref)
    for kind in ((".w", ".v"), (".phi", ".s")):
        names = [n for n in _state_names(ref) if n.endswith(kind)]
        scale = max(float(np.ptp(ref[n])) for n in names)
        err = max(float(np.abs(np.interp(ref.t, res.t, res[n]) - ref[n]).max()) for n in names) / scale
        assert err <= accuracy, (kind, err)
    usual = m.simulate(t_end, dt_out=1e-2, accuracy=accuracy, native=False)
    assert "native" not in usual.stats.extra
    assert _path(res) == _path(usual)


def test_native_friction_run_with_a_time_limit_stays_native():
    res = coupled_clutches().simulate(1.5, dt_out=1e-3, solver="ida", native=True, timeout_s=600)
    assert res.stats.extra["native"] is True and res.stats.events == 9


class StickyClutch(Clutch):
    """A user's clutch with its own kinetic law (friction rising with slip)."""

    def kinetic(self, w_abs, t, left=False):
        tk, dk = super().kinetic(w_abs, t, left)
        return tk * (1.0 + 0.1 * w_abs), dk * (1.0 + 0.1 * w_abs) + 0.1 * tk


@pytest.mark.parametrize("variant, reason", [
    (lambda m: setattr(m.components["clutch1"], "mu_table", [[0.0, 0.5], [5.0, 0.3]]), "speed-dependent"),
    (lambda m: setattr(m.components["clutch1"], "mu_law", Stribeck(mu_s=0.5, mu_k=0.3, w_s=1.0)), "speed-dependent"),
])
def test_friction_laws_the_kernels_cannot_evaluate_run_the_usual_path(variant, reason):
    m = coupled_clutches()
    variant(m)
    res = m.simulate(1.5, dt_out=1e-2, solver="ida", native=True)
    note = res.stats.extra["native"]
    assert isinstance(note, str) and note.startswith("not used") and reason in note and "clutch1" in note
    plain = m.simulate(1.5, dt_out=1e-2, solver="ida")
    np.testing.assert_array_equal(res["J1.w"], plain["J1.w"])


def test_a_subclass_with_its_own_law_is_not_native():
    assert StickyClutch("s", fn_max=1.0).linear_law() is None
    assert Clutch("c", fn_max=2.0, mu=0.4, cgeo=0.5, peak=1.2).linear_law()[1:] == (2.0, 0.4 * 0.5, 1.2)


@pytest.mark.parametrize("rtol", [1e-6, 1e-9])
def test_one_way_clutch_runs_native_on_the_python_path_s_events(rtol):
    """MSL OneWayClutch: the freewheel locks where w_rel reaches 0 and releases forward past its capacity
    (engaged) or its small hold (disengaged), evaluated by the compiled event function: the same mode changes
    at the same instants as on the Python path, the answers within the tolerance."""
    from regmech.components import OneWayClutch
    from regmech.library import one_way_clutch
    law = OneWayClutch("o", fn_max=10.0, mu=0.3, cgeo=2.0, peak=1.0).one_way_law()
    assert law[1:] == (10.0, 0.6, 1.0 + OneWayClutch.EPS0, OneWayClutch.EPS0 * 0.6 * 10.0)
    m = one_way_clutch()
    native = m.simulate(2.0, dt_out=2e-3, solver="ida", rtol=rtol, native=True)
    usual = m.simulate(2.0, dt_out=2e-3, solver="ida", rtol=rtol, native=False)
    assert native.stats.extra["native"] is True
    assert [(e.component, e.old_mode, e.new_mode) for e in native.events] == \
        [(e.component, e.old_mode, e.new_mode) for e in usual.events]
    assert len(native.events) >= 6
    assert max(abs(a.t - b.t) for a, b in zip(native.events, usual.events)) < 1e3 * rtol
    np.testing.assert_allclose(native.t, usual.t, rtol=0, atol=1e3 * rtol)      # event rows: their instants
    for name in ("inertiaIn.w", "inertiaOut.w", "oneWayClutch.tau"):
        np.testing.assert_allclose(native[name], usual[name], rtol=0, atol=1e2 * rtol * np.ptp(usual[name]))


@pytest.mark.parametrize("device", [
    Clutch("c", mu=0.35, cgeo=0.8, peak=1.4, fn_max=50.0, f_normalized=Sine(amplitude=1.0, freq_hz=2.0)),
    Brake("b", mu=0.6, peak=1.1, fn_max=10.0, f_normalized=Ramp(height=1.0, duration=0.3, start_time=0.1)),
    Clutch("t", mu_table=[[0.0, 0.45]], fn_max=5.0, f_normalized=Step(height=-2.0, offset=1.0, start_time=0.2)),
    FrictionContact("f", mu=0.5, peak=1.2, fn=Sine(amplitude=3.0, freq_hz=1.0, offset=1.0)),
])
def test_linear_law_restates_the_device_s_own_methods(device):
    """What the kernels evaluate (``linear_law``) is what the device's methods say, at any time and speed."""
    sig, fn_scale, k, peak = device.linear_law()
    cap = device.capacity_function()
    for t in np.linspace(0.0, 1.0, 23):
        for left in (False, True):
            fn = fn_scale * sig.value(t, left)
            assert fn == pytest.approx(device.normal_force(t, left), rel=1e-14, abs=1e-14)
            for w in (0.0, 0.7, 30.0):
                assert k * max(fn, 0.0) == pytest.approx(device.kinetic(w, t, left)[0], rel=1e-14, abs=1e-14)
            got = cap(t, left)
            assert got[1] == pytest.approx(k * max(fn, 0.0), rel=1e-14, abs=1e-14)
            assert got[2] == pytest.approx(peak * k * max(fn, 0.0), rel=1e-14, abs=1e-14)


@pytest.mark.parametrize("native", [True, False])
def test_a_repeated_run_equals_a_fresh_model_s_first_run(native):
    """A compiled system keeps its native solvers and the start of its mode logic between runs (set up once):
    the next run, and a run after a parameter change, give what a fresh model gives."""
    m = brake_and_clutch()
    kw = dict(dt_out=1e-2, solver="ida", rtol=1e-7, native=native)
    first, again = m.simulate(3.0, **kw), m.simulate(3.0, **kw)
    fresh = brake_and_clutch().simulate(3.0, **kw)
    for name in ("J1.w", "J2.w", "J3.w", "brake.tau"):
        np.testing.assert_array_equal(again[name], fresh[name])
        np.testing.assert_array_equal(first[name], fresh[name])
    m.components["J1"].w0 = 1.0
    changed = m.simulate(3.0, **kw)
    other = brake_and_clutch()
    other.components["J1"].w0 = 1.0
    np.testing.assert_array_equal(changed["J2.w"], other.simulate(3.0, **kw)["J2.w"])
    assert _path(changed) != _path(first) or not np.array_equal(changed["J2.w"], first["J2.w"])


@pytest.mark.parametrize("key", ["coupled_clutches", "brake_and_clutch", "sliding_blocks"])
def test_kernels_evaluate_the_residual_and_event_functions_of_every_mode_set(key):
    """The compiled residual and event functions against the hybrid layer's own (``CompiledSystem.residual``,
    ``FrictionSet.event_values``) at random states and times, in every combination of modes and engagement:
    the kernels restate the friction laws, so any difference would be a silent wrong answer."""
    import ctypes
    import itertools
    from regmech.hybrid import attach
    from regmech.modes import BACKWARD, FORWARD, FREE, HELD, STUCK  # noqa: F401
    from regmech.solvers.ida import _Ordering
    m = SCENES[key][0]()
    c = attach(m.compile())
    fr = c.friction
    N = c.N
    solver = ida_native.NativeIDA(c, 1e-6, np.full(N, 1e-8), "dense", _Ordering(N), None, 5, 500)
    K = solver.K
    rng = np.random.default_rng(7)
    gout, ref = np.zeros(2 * fr.mf), np.zeros(N)
    as_double = ctypes.POINTER(ctypes.c_double)
    lib = solver.lib
    rr = lib.nv_new(N, solver._handles[4])            # the residual kernel writes into an N_Vector
    res = np.ctypeslib.as_array(ctypes.cast(lib.nv_ptr(rr), as_double), (N,))
    for modes in itertools.product((STUCK, FORWARD, BACKWARD, FREE, HELD), repeat=fr.mf):
        modes = np.array(modes)
        fr.engaged = rng.random(fr.mf) < 0.5
        fr._relief = []
        solver.set_segment(modes, np.full(N, 1e-8))
        for _ in range(3):
            t = float(rng.uniform(0.0, 2.0))
            c._t_right = t if rng.random() < 0.3 else np.inf        # left limits at a segment's end too
            solver.fdata[0] = c._t_right
            y, yp = rng.standard_normal(N) * 3.0, rng.standard_normal(N) * 3.0
            solver.ya[:], solver.ypa[:] = y, yp
            fr._small_for = fr._at_segment = None
            fr._ev_key = None
            assert K.events.ctypes(t, solver.yy, solver.yp, gout.ctypes.data_as(as_double),
                                   solver.user.ctypes.data) == 0
            np.testing.assert_allclose(gout, fr.event_values(t, y, yp, modes), rtol=1e-13, atol=1e-13)
            assert K.residual_friction.ctypes(t, solver.yy, solver.yp, rr, solver.user.ctypes.data) == 0
            c.residual(t, y, yp, ref, modes)
            np.testing.assert_allclose(res, ref, rtol=1e-12, atol=1e-12)
    lib.nv_free(rr)


def test_a_clutch_engaging_at_zero_slip_does_not_miss_its_reversal():
    """brake_and_clutch on the Python callbacks at rtol 3e-7 (the rtol the accuracy contract tightens 1e-4 to):
    the clutch re-engaged (its Sine normal force turning positive) at a w_rel of round-off size and took the
    direction of that round-off's sign; its guard (mode * w_rel) started at zero, which IDA's root finding leaves
    inactive, so the slip passed zero unseen and at the brake's next event (t = 2.805 s) the clutch was sliding
    Backward at w_rel = +0.125 (J3.w 6 % of its range off, the clutch supplying 0.40 W; the restart check
    then refused the run). Engaging within round-off of zero slip is Stuck now, and the holding-torque check
    decides the break-away."""
    build, t_end = SCENES["brake_and_clutch"]
    res = build().simulate(t_end, dt_out=1e-2, solver="ida", rtol=3e-7, native=False)
    ref = build().simulate(t_end, dt_out=1e-2, solver="ida", rtol=1e-11, atol=1e-13, native=False)
    assert _path(res) == _path(ref)
    for name in ("J1.w", "J2.w", "J3.w"):
        err = np.max(np.abs(np.interp(ref.t, res.t, res[name]) - ref[name])) / np.ptp(ref[name])
        assert err < 1e-4, (name, err)
    p = res["clutch.power"]
    assert p.min() >= -1e-9 * np.abs(p).max()


def test_auto_falls_back_without_idas_native_option(monkeypatch):
    """When ida refuses under solver="auto", the next candidate runs without ida's own option ``native``
    (it was refused as an unknown option of expm)."""
    from regmech.solvers import auto
    real = auto.simulate_with_accuracy

    def refusing(model, solver, *args):
        if solver == "ida":
            raise rm.SimulationError("refused for the test")
        return real(model, solver, *args)
    monkeypatch.setattr(auto, "simulate_with_accuracy", refusing)
    res = coupled_clutches().simulate(0.5, dt_out=1e-2, accuracy=1e-3, native=False)
    assert res.stats.solver != "ida" and "refused for the test" in res.stats.extra["auto_reason"]


@pytest.mark.parametrize("key", ["friction_chain_band", "chain_band"])
def test_band_jacobian_kernel_is_the_system_jacobian_in_every_mode_set(key):
    """The closed-form band Jacobian (``_native_kernels.jacobian_band``, which replaced IDA's difference quotients
    on band runs) against the compiled system's own ``dF/dy + cj dF/dy'`` in the solver's ordering, for several
    ``cj`` and every mode of the friction rows: the band storage's places are computed by regmech, so a place
    off by one would be a wrong Jacobian (slower Newton iterations or failed steps, and a wrong answer where
    the iteration stopped early)."""
    import ctypes
    import itertools
    from regmech.bench.hard_models import benchmark_chain
    from regmech.hybrid import attach
    from regmech.modes import BACKWARD, FORWARD, FREE, STUCK
    from regmech.solvers.ida import _band_widths, choose_linsolver
    m = friction_chain() if key == "friction_chain_band" else benchmark_chain(70)
    c = attach(m.compile())
    N = c.N
    linsolver, order = choose_linsolver(c)
    assert linsolver == "band" and order.perm is not None
    lb, ub = _band_widths(c, order)
    solver = ida_native.NativeIDA(c, 1e-6, np.full(N, 1e-8), "band", order, None, 5, 500, lb, ub)
    K, lib = solver.K, solver.lib
    assert solver._jac is K.jacobian_band
    A = solver._opts[2]
    s_mu, ldim, ldata = lib.band_smu(A), lib.band_ldim(A), lib.band_ldata(A)
    data = np.ctypeslib.as_array(ctypes.cast(lib.band_data(A), ctypes.POINTER(ctypes.c_double)), (ldata,))
    z = np.zeros(N)
    mode_sets = list(itertools.product((STUCK, FORWARD, BACKWARD, FREE), repeat=c.mf)) if c.mf else [None]
    for modes in mode_sets[:: max(1, len(mode_sets) // 40)]:
        if modes is not None:
            modes = np.array(modes)
            jc, jcj = ida_native.friction_jacobian(c, modes)
            solver.fdata[solver._jc], solver.fdata[solver._jcj] = jc, jcj
        for cj in (0.0, 1.0, 3.7e4):
            data[:] = np.nan             # every place of the storage is written (zero outside the pattern)
            assert K.jacobian_band.ctypes(0.0, cj, None, None, None, A, solver.user.ctypes.data, None, None,
                                          None) == 0
            got = np.zeros((N, N))
            for j in range(N):
                for i in range(max(0, j - ub), min(N, j + lb + 1)):
                    got[i, j] = data[j * ldim + i - j + s_mu]
            want = np.zeros((N, N))
            want[c.jac.rows, c.jac.cols] = c.jacobian_data(0.0, z, z, cj, modes)
            want = want[order.perm][:, order.perm]
            # (the kernel forms jc + cj jcj, the system its own sum: the same to round-off)
            np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14 * max(1.0, float(np.abs(want).max())))
            assert np.array_equal(got != 0, want != 0)
            assert not np.isnan(data).any()


@pytest.mark.parametrize("solver", [dict(), dict(solver="ida", native=True)])
def test_a_stribeck_clutch_breaks_away_under_the_default_call(solver):
    """A ``mu_law`` overrides ``mu``; ``linear_law`` read the constant ``mu`` (0.5 by default) as the clutch's law, so
    the compiled path, which the default call takes, held a clutch of mu_s = 0.6 under a ramp torque for the whole
    run: no break-away at t = 0.6 s (mu_s cgeo fn = 6 N m), no error. Found by the stick/slip validation tests when
    ida ran natively by default."""
    m = rm.Model("break")
    g = m.add(Fixed("g"))
    tq = m.add(Torque("tq", tau=Ramp(height=10.0, duration=1.0)))
    J1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=0.0))
    cl = m.add(Clutch("cl", fn_max=10.0, mu_law=Stribeck(mu_s=0.6, mu_k=0.4, w_s=0.5)))
    m.connect(tq.flange, J1.flange_a)
    m.connect(J1.flange_b, cl.flange_a)
    m.connect(cl.flange_b, g.flange)
    assert cl.linear_law() is None
    res = m.simulate(1.0, dt_out=1e-3, **solver)
    assert len(res.events) == 1 and res.events[0].t == pytest.approx(0.6, abs=1e-6)


def test_bearing_friction_of_constant_torque_runs_native_and_a_speed_table_does_not():
    """The excavator's swing bearing (MSL BearingFriction with one torque): native, the events and answers of
    the Python path; a torque table that varies with speed keeps the Python callbacks, named."""
    from regmech.components import BearingFriction
    from regmech.library import excavator_swing
    assert BearingFriction("b", tau_table=[(0.0, 3.0)], peak=1.5).linear_law()[1:] == (1.0, 3.0, 1.5)
    assert BearingFriction("b", tau_table=[(0.0, 3.0), (10.0, 4.0)]).linear_law() is None
    m = excavator_swing()
    native = m.simulate(2.0, dt_out=2e-3, solver="ida", rtol=1e-8, native=True)
    usual = m.simulate(2.0, dt_out=2e-3, solver="ida", rtol=1e-8, native=False)
    assert native.stats.extra["native"] is True
    # the two backlashes meet their contacts at one instant, in either order
    key = [sorted((round(e.t, 6), e.component, e.new_mode) for e in r.events) for r in (native, usual)]
    assert key[0] == key[1] and len(key[0]) >= 5
    # on the output grid's rows (an event within round-off of a grid point adds a row on one path only)
    grid = np.round(np.arange(0.0, 2.0 + 1e-9, 2e-3), 12)
    rows = [np.searchsorted(np.round(r.t, 12), grid) for r in (native, usual)]
    for name in ("turntable.w", "swing_friction.tau", "backlash_1.tau"):
        np.testing.assert_allclose(native[name][rows[0]], usual[name][rows[1]], rtol=0,
                                   atol=1e-5 * np.ptp(usual[name]))
    m.components["swing_friction"].tau_table = [(0.0, 2000.0), (1.0, 2500.0)]
    note = m.simulate(0.5, dt_out=1e-2, solver="ida", native=True).stats.extra["native"]
    assert "BearingFriction 'swing_friction'" in note and "speed-dependent" in note
