"""Bad signals and parameters give a regmech error that names the component, the signal and the time.

Regression tests: non-finite or out-of-range signal values, callables that raise or take the wrong
arguments, parameter tables edited in place, too many time events, prescribed motions that would
need an impulse.
"""

import math
import re

import numpy as np
import pytest

import regmech as rm
from regmech.components import (BearingFriction, Clutch, Engine, Fixed, Force, FrictionContact, Inertia,
                                 LinearSpeed, LossyGear, Mass, Position, Speed, Spring, SpringDamper, Torque,
                                 TwoFlangeCompliant)
from regmech.library import coupled_clutches
from regmech.signals import Function, Pulse, Ramp, Signal, Sine, Step, Table, as_signal

SOLVERS = ["ida", "scipy:DOP853"]


def _at(message):
    """The time an error message gives (``t=... s``)."""
    found = re.search(r"t=([-0-9.e+]+) s", message)
    assert found, message
    return float(found.group(1))


# ----------------------------------------------------------------- non-finite signal values
@pytest.mark.parametrize("solver", SOLVERS)
def test_nan_normal_force_is_an_error_not_disengaged(solver):
    m = coupled_clutches()
    m["clutch1"].f_normalized = lambda t: float("nan")
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(1.5, solver=solver)
    msg = str(err.value)
    assert "Clutch 'clutch1'" in msg and "'f_normalized'" in msg and "nan" in msg
    assert _at(msg) == 0.0


def _driven(source, body=None):
    """A source on a mass joined by a spring to a second one."""
    m = rm.Model("driven")
    dom = source.domain
    src = m.add(source)
    a = m.add(body or (Inertia("a", J=1.0) if dom == "rotational" else Mass("a", m=1.0)))
    k = m.add(Spring("k", c=100.0, domain=dom))
    b = m.add(Inertia("b", J=1.0) if dom == "rotational" else Mass("b", m=1.0))
    m.connect(src.flange, a.flange_a)
    m.connect(a.flange_b, k.flange_a)
    m.connect(k.flange_b, b.flange_a)
    return m


def _late(value, t_bad=0.7):
    """A smooth signal that turns ``value`` from ``t_bad`` on (no breakpoint declared)."""
    return lambda t: 0.2 * math.sin(3.0 * t) if t < t_bad else value


LATE_CASES = [
    (lambda f: Torque("src", tau=f), "Torque 'src'", "tau"),
    (lambda f: Engine("src", torque_map=[(0.0, 1.0), (100.0, 1.0)], throttle=f), "Engine 'src'", "throttle"),
    (lambda f: Force("src", f=f), "Force 'src'", "'f'"),
    (lambda f: Speed("src", w_ref=f), "Speed 'src'", "w_ref"),
    (lambda f: Position("src", phi_ref=f), "Position 'src'", "phi_ref"),
]


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("bad", [float("nan"), math.inf, -math.inf])
@pytest.mark.parametrize("make, comp, sig", LATE_CASES)
def test_a_signal_that_turns_non_finite_later_is_named_with_its_time(make, comp, sig, bad, solver, capfd):
    m = _driven(make(_late(bad)))
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(1.5, solver=solver)
    msg = str(err.value)
    assert comp in msg and sig in msg and "finite" in msg
    assert "max_steps" not in msg
    t = _at(msg)
    assert 0.7 - 3e-3 <= t <= 1.5          # Function.derivative samples 1e-4 .. 2e-3 around the solver's t
    assert "IDA" not in capfd.readouterr().err     # no SUNDIALS line on stderr


def test_friction_contact_normal_force_nan_is_named():
    m = rm.Model("block")
    wall = m.add(Fixed("wall", domain="translational"))
    push = m.add(Force("push", f=Sine(amplitude=5.0, freq_hz=1.0)))
    block = m.add(Mass("block", m=1.0))
    contact = m.add(FrictionContact("contact", mu=0.3, fn=_late(float("nan"), 0.4)))
    m.connect(push.flange, block.flange_a)
    m.connect(block.flange_b, contact.flange_a)
    m.connect(contact.flange_b, wall.flange)
    with pytest.raises(rm.SimulationError, match=r"FrictionContact 'contact': signal 'fn'.*nan"):
        m.simulate(1.0)


def test_a_user_signal_subclass_is_checked_too():
    class Drifting(Signal):
        def value(self, t, left=False):
            return 0.1 if t < 0.5 else float("inf")

        def derivative(self, t, order=1, left=False):
            return 0.0

    m = _driven(Torque("src", tau=Drifting()))
    assert repr(m["src"].tau) == "Drifting()"
    with pytest.raises(rm.SimulationError, match=r"Torque 'src': signal 'tau'.*inf"):
        m.simulate(1.0)


def test_builtin_signals_are_finite_by_construction():
    with pytest.raises(rm.ParameterError, match="Sine"):
        Sine(amplitude=1e308, offset=1e308)
    with pytest.raises(rm.ParameterError, match="Sine"):
        Sine(amplitude=1.0, freq_hz=1e160)           # its second derivative overflows
    with pytest.raises(rm.ParameterError, match="Ramp"):
        Ramp(height=1e300, duration=1e-300)
    with pytest.raises(rm.ParameterError, match="Table"):
        Table([(0.0, 0.0), (1e-320, 1e10)])
    with pytest.raises(rm.ParameterError, match="Step"):
        Step(height=1e308, offset=1e308)


# --------------------------------------------------------------------------- documented range
def test_normal_force_above_one_is_refused_when_given():
    with pytest.raises(rm.ParameterError, match=r"Clutch 'c'.*'f_normalized'.*above its upper bound 1.*fn_max"):
        Clutch("c", fn_max=10.0, f_normalized=5.0)
    c = Clutch("c", fn_max=10.0)
    with pytest.raises(rm.ParameterError, match=r"Clutch 'c'.*reaches 1.5"):
        c.f_normalized = Sine(amplitude=1.0, offset=0.5)
    with pytest.raises(rm.ParameterError, match=r"reaches 2"):
        c.f_normalized = Table([(0.0, 0.0), (1.0, 2.0)])
    c.f_normalized = Sine(amplitude=1.0, phase=math.pi / 2)     # MSL CoupledClutches: down to -1 is fine
    c.f_normalized = 1.0


def test_normal_force_callable_above_one_is_refused_at_its_time():
    m = coupled_clutches()
    m["clutch2"].f_normalized = lambda t: 0.0 if t < 0.4 else 5.0
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(1.5)
    msg = str(err.value)
    assert "Clutch 'clutch2'" in msg and "f_normalized" in msg and "above its upper bound 1" in msg
    assert _at(msg) >= 0.4


def test_negative_normal_force_disengages_like_zero():
    runs = []
    for f in (0.0, -1.0, Step(height=-1.0, start_time=0.2)):
        m = coupled_clutches()
        m["clutch1"].f_normalized = f
        runs.append(m.simulate(1.5, dt_out=0.01, solver="ida", rtol=1e-8))
    for res in runs[1:]:
        assert set(np.unique(res["clutch1.mode"])) == {2}       # Free throughout
        for name in ("J1.w", "J2.w", "J4.w"):
            np.testing.assert_allclose(np.interp(runs[0].t, res.t, res[name]), runs[0][name], rtol=0, atol=1e-6)


# ------------------------------------------------------------------ callables
def test_a_callable_that_raises_is_named_with_the_time_of_the_call():
    calls = []

    def tau(t):
        calls.append(t)
        return 1.0 / (t - t) if t > 0.3 else 0.0

    m = coupled_clutches()
    m["torque"].tau = tau
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(1.5)
    msg = str(err.value)
    assert "Torque 'torque'" in msg and "signal 'tau'" in msg and "ZeroDivisionError" in msg
    assert isinstance(err.value.__cause__, ZeroDivisionError)
    assert _at(msg) == pytest.approx(calls[-1], rel=1e-8) and calls[-1] > 0.3


def test_a_callable_returning_a_non_number_is_named():
    m = coupled_clutches()
    m["torque"].tau = lambda t: "ten"
    with pytest.raises(rm.SimulationError, match=r"Torque 'torque': signal 'tau'.*returned 'ten'"):
        m.simulate(1.5)


@pytest.mark.parametrize("func", [lambda: 1.0, lambda t, x: 1.0, lambda *, t: 1.0])
def test_a_callable_with_the_wrong_arguments_is_refused_when_given(func):
    with pytest.raises(rm.ParameterError, match=r"Torque 'drive': parameter 'tau'.*f\(t\)"):
        Torque("drive", tau=func)
    c = Clutch("c", fn_max=1.0)
    with pytest.raises(rm.ParameterError, match=r"Clutch 'c': parameter 'f_normalized'"):
        c.f_normalized = func
    with pytest.raises(rm.ParameterError, match="f\\(t\\)"):
        Function(func)


def test_callables_of_one_argument_in_any_form_are_accepted():
    import functools

    class Law:
        def __call__(self, t):
            return 2.0 * t

    for f in (math.sin, Law(), functools.partial(lambda a, t: a * t, 3.0), lambda t, k=2: k * t, np.sin):
        assert np.isfinite(Torque("drive", tau=f).tau.value(0.5))
    with pytest.raises(rm.ParameterError, match="instance"):
        Torque("drive", tau=Sine)


def test_a_signal_bound_to_a_part_is_named_through_its_subsystem():
    from regmech.library import vehicle_launch
    m = vehicle_launch()
    m["wheel_left.road_contact"].fn = _late(float("nan"), 0.05)
    with pytest.raises(rm.SimulationError, match=r"FrictionContact 'wheel_left.road_contact': signal 'fn'"):
        m.simulate(0.3)


def test_rebinding_keeps_the_callable_and_names_the_new_owner():
    f = lambda t: float("nan")   # noqa: E731
    a = Torque("a", tau=f)
    b = Torque("b", tau=a.tau)
    assert b.tau.func is f
    with pytest.raises(rm.SimulationError, match="Torque 'b'"):
        b.tau.value(0.0)
    with pytest.raises(rm.SimulationError, match="Torque 'a'"):
        a.tau.value(0.0)
    free = as_signal(f)
    with pytest.raises(rm.SimulationError, match="signal 'value'"):
        free.value(1.0)


# ---------------------------------------------------------------- read-only tables
def test_a_validated_table_cannot_be_edited_in_place():
    m = coupled_clutches()
    m["clutch1"].mu_table = [[0.0, 0.5], [10.0, 0.4]]
    with pytest.raises(ValueError, match="read-only"):
        m["clutch1"].mu_table[:, 1] = -5.0
    table = np.array([[0.0, 0.5], [10.0, 0.4]])
    c = Clutch("c", fn_max=1.0, mu_table=table)
    table[:, 1] = -5.0                              # the caller's array is not the clutch's
    assert np.all(c.mu_table[:, 1] > 0)
    for arr in (BearingFriction("b", tau_table=[(0.0, 1.0)]).tau_table,
                LossyGear("g", ratio=2.0, loss_table=[[0.0, 0.9, 0.9, 0.0, 0.0]]).loss_table,
                Engine("e", torque_map=[(0.0, 100.0), (500.0, 150.0)]).torque_map,
                Table([(0.0, 1.0), (1.0, 2.0)]).points):
        with pytest.raises(ValueError, match="read-only"):
            arr[0, 1] = -1.0


@pytest.mark.parametrize("sig, name", [(Sine(amplitude=2.0, freq_hz=3.0), "freq_hz"), (Step(height=1.0), "height"),
                                       (Ramp(height=1.0, duration=0.5), "duration"), (Pulse(), "period"),
                                       (Table([(0.0, 1.0), (1.0, 2.0)]), "points"),
                                       (rm.signals.Constant(3.0), "value_")])
def test_a_library_signal_cannot_be_changed_in_place(sig, name):
    # the native IDA kernels and the vectorised signal banks keep a compiled model's signal parameters: a
    # Sine's freq_hz changed after a run reached the Python solvers but not native IDA (same model, answers
    # 0.56 rad/s apart), with no check of the new value
    before = repr(sig)
    with pytest.raises(rm.ParameterError, match=rf"{type(sig).__name__}: parameter '{name}' cannot be changed in "
                                                rf"place.*assign it to the component's parameter"):
        setattr(sig, name, 1.0)
    with pytest.raises(rm.ParameterError, match="cannot be removed"):
        del sig._frozen                                 # the freeze itself cannot be undone either
    assert repr(sig) == before


@pytest.mark.parametrize("native", [True, False])
def test_a_new_signal_assigned_to_the_component_is_what_every_ida_path_runs(native):
    from regmech.bench.hard_models import benchmark_chain
    m = benchmark_chain(10, tau=Sine(amplitude=10.0, freq_hz=5.0))
    first = m.simulate(0.5, 0.01, solver="ida", rtol=1e-8, native=native)
    m["drive"].tau = Sine(amplitude=10.0, freq_hz=2.0)
    again = m.simulate(0.5, 0.01, solver="ida", rtol=1e-8, native=native)
    fresh = benchmark_chain(10, tau=Sine(amplitude=10.0, freq_hz=2.0)).simulate(0.5, 0.01, solver="ida", rtol=1e-8,
                                                                               native=native)
    assert np.array_equal(again["J0.w"], fresh["J0.w"])
    assert np.max(np.abs(again["J0.w"] - first["J0.w"])) > 0.1


def test_a_users_signal_subclass_keeps_its_own_attributes():
    import copy
    import pickle

    class Chirp(Sine):
        def __init__(self, rate):
            super().__init__(amplitude=1.0, freq_hz=1.0)
            self.rate = rate

    c = Chirp(2.0)
    c.rate = 3.0
    assert c.rate == 3.0
    s = Sine(amplitude=2.0, freq_hz=3.0)
    for again in (copy.deepcopy(s), pickle.loads(pickle.dumps(s))):
        assert repr(again) == repr(s) and again.value(0.1) == s.value(0.1)
        with pytest.raises(rm.ParameterError):
            again.freq_hz = 1.0


def test_a_table_assigned_after_construction_is_checked_at_compile():
    m = coupled_clutches()
    m["clutch1"].mu_table = [[0.0, 0.5], [10.0, -0.4]]      # negative friction coefficient
    with pytest.raises(rm.ParameterError, match=r"Clutch 'clutch1'.*mu_table"):
        m.simulate(1.5)


def test_a_loss_table_assigned_after_construction_is_used():
    def run(table_at_construction, table_later):
        m = rm.Model("g")
        drive = m.add(Torque("drive", tau=10.0))
        a = m.add(Inertia("a", J=1.0))
        g = m.add(LossyGear("gear", ratio=2.0, loss_table=table_at_construction))
        b = m.add(Inertia("b", J=1.0))
        m.connect(drive.flange, a.flange_a)
        m.connect(a.flange_b, g.flange_a)
        m.connect(g.flange_b, b.flange_a)
        if table_later is not None:
            g.loss_table = table_later
        return m.simulate(0.5, dt_out=0.1)["b.w"]

    lossy = [[0.0, 0.5, 0.5, 0.0, 0.0]]
    np.testing.assert_allclose(run([[0.0, 1.0, 1.0, 0.0, 0.0]], lossy), run(lossy, None), rtol=1e-9)


# ----------------------------------------------------------------- time events
def _pulsed(pulse):
    m = rm.Model("pulsed")
    drive = m.add(Torque("drive", tau=pulse))
    J = m.add(Inertia("J", J=1.0, phi0=0.0, w0=0.0))
    d = m.add(SpringDamper("k", c=100.0, d=1.0))
    m.connect(drive.flange, J.flange_a)
    m.connect(J.flange_b, d.flange_a)
    m.connect(d.flange_b, m.add(Fixed("ground")).flange)
    return m


@pytest.mark.parametrize("solver", ["ida", "scipy:RK45", "rk4"])
@pytest.mark.parametrize("period, t_end, count", [(1e-8, 1.0, 2e8), (1e-2, 1e4, 2e6)])
def test_too_many_time_events_are_refused_before_the_run(period, t_end, count, solver):
    m = _pulsed(Pulse(amplitude=1.0, period=period))
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(t_end, solver=solver)
    msg = str(err.value)
    assert "Torque 'drive'" in msg and "signal 'tau'" in msg and "max_time_events" in msg
    n = int(re.search(r"declare about ([0-9,]+)", msg).group(1).replace(",", ""))
    assert abs(n - count) <= 4


def test_the_time_event_limit_is_an_option():
    m = _pulsed(Pulse(amplitude=1.0, period=0.1))          # 20 time events in 1 s
    with pytest.raises(rm.SimulationError, match="max_time_events=10"):
        m.simulate(1.0, max_time_events=10)
    res = m.simulate(1.0, max_time_events=20)
    assert res.stats.segments >= 19
    for bad in (-1, 1.5, "100", True):
        with pytest.raises(rm.ParameterError, match="max_time_events"):
            m.simulate(1.0, max_time_events=bad)


def test_pulse_counts_its_breakpoints_without_listing_them():
    rng = np.random.default_rng(7)
    for _ in range(300):
        p = Pulse(period=float(rng.choice([0.01, 0.1, 0.3])), width=float(rng.choice([10.0, 50.0, 99.0])),
                  start_time=float(rng.choice([0.0, 0.05, 0.33])))
        a = float(rng.uniform(-1.0, 2.0))
        b = a + float(rng.uniform(0.0, 5.0))
        listed = {x for x in p.breakpoints(a, b) if a < x < b}
        assert abs(p.count_breakpoints(a, b) - len(listed)) <= 2


def test_many_time_events_agree_with_a_smooth_reference():
    # 400 pulse edges; the answer of ida with all its restarts matches DOP853 (on output instants
    # that are no breakpoints, where both record one row)
    m = _pulsed(Pulse(amplitude=1.0, period=0.01, width=30.0))
    dt = 0.0137
    res = m.simulate(2.0, dt_out=dt, solver="ida", rtol=1e-8)
    ref = m.simulate(2.0, dt_out=dt, solver="scipy:DOP853", rtol=1e-10, atol=1e-12)
    assert res.stats.segments >= 400

    def on_grid(r):
        k = np.round(r.t / dt)
        keep = np.abs(r.t - k * dt) < 1e-12
        return dict(zip(k[keep].astype(int), r["J.w"][keep]))

    a, b = on_grid(res), on_grid(ref)
    assert len(a) >= 140 and a.keys() == b.keys()
    diff = max(abs(a[k] - b[k]) for k in a)
    assert diff <= 1e-5 * max(abs(v) for v in b.values())


# --------------------------------------------------------- prescribed motion needing an impulse
@pytest.mark.parametrize("solver", ["ida", "scipy:RK45"])
@pytest.mark.parametrize("source, what", [
    (lambda: Speed("src", w_ref=Step(height=1.0, start_time=0.5)), "jumps at t=0.5 s"),
    (lambda: Speed("src", w_ref=Table([(0.0, 0.0), (0.5, 0.0), (0.5, 1.0)])), "jumps at t=0.5 s"),
    (lambda: LinearSpeed("src", v_ref=Step(height=2.0, start_time=0.25)), "jumps at t=0.25 s"),
    (lambda: Position("src", phi_ref=Step(height=1.0, start_time=0.2)), "jump at t=0.2 s"),
    (lambda: Position("src", phi_ref=Ramp(height=1.0, duration=0.3, start_time=0.2)), "corner at t=0.2 s"),
])
def test_a_prescribed_motion_that_needs_an_impulse_is_refused(source, what, solver):
    src = source()
    m = _driven(src)
    with pytest.raises(rm.SimulationError) as err:
        m.simulate(1.0, solver=solver)
    msg = str(err.value)
    assert f"{type(src).__name__} 'src'" in msg and what in msg and "impulse" in msg
    assert "Ramp" in msg                                   # the remedy


def test_references_continuous_inside_the_run_are_accepted():
    for src in (Speed("src", w_ref=Ramp(height=1.0, duration=0.3, start_time=0.2)),
                Speed("src", w_ref=Step(height=1.0, start_time=0.0)),      # at t_start: the start value
                Position("src", phi_ref=Ramp(height=0.1, duration=2.0)),   # corners at 0 and 2, outside
                Position("src", phi_ref=Sine(amplitude=0.1, freq_hz=1.0))):
        res = _driven(src).simulate(1.0, dt_out=0.1)
        assert np.all(np.isfinite(res["b.w"]))


def test_time_events_restart_the_same_ida_solver(monkeypatch):
    # a run with hundreds of time events and no mode change builds one IDA solver, not one per
    # segment (building one costs about a dozen residual calls); the answer is the same. The Python
    # path's reuse rule (``_reusable``); the native path keeps one solver per run by construction
    import regmech.solvers.ida as ida
    built = []
    make = ida._make_solver
    monkeypatch.setattr(ida, "_make_solver", lambda *a, **k: built.append(1) or make(*a, **k))
    m = _pulsed(Pulse(amplitude=1.0, period=0.01, width=30.0))
    res = m.simulate(2.0, dt_out=0.01, solver="ida", native=False)
    assert res.stats.segments >= 400 and len(built) <= 2
    monkeypatch.setattr(ida, "_reusable", lambda *a: None)
    fresh = m.simulate(2.0, dt_out=0.01, solver="ida", native=False)
    assert len(built) >= 400
    np.testing.assert_allclose(res["J.w"], fresh["J.w"], rtol=0, atol=1e-12 * np.max(np.abs(fresh["J.w"])))


@pytest.mark.parametrize("solver", ["ida", "scipy:RK45"])
def test_a_jumping_speed_reference_is_named_not_an_empty_contradiction(solver):
    # on main: "inconsistent start velocities: the fixed start values of [] contradict ..." (RK45)
    # or a generic error-test failure (ida)
    from regmech.components import Brake
    m = rm.Model("held")
    src = m.add(Speed("src", w_ref=Step(height=1.0, start_time=0.3)))
    J = m.add(Inertia("J", J=1.0))
    c = m.add(Clutch("c", fn_max=100.0))
    J2 = m.add(Inertia("J2", J=1.0))
    b = m.add(Brake("b", fn_max=1000.0))
    m.connect(src.flange, J.flange_a)
    m.connect(J.flange_b, c.flange_a)
    m.connect(c.flange_b, J2.flange_a)
    m.connect(J2.flange_b, b.flange)
    with pytest.raises(rm.SimulationError, match=r"Speed 'src': its reference 'w_ref'.*jumps at t=0.3 s.*Ramp"):
        m.simulate(1.0, solver=solver)


@pytest.mark.parametrize("kw", [{}, {"solver": "ida", "accuracy": 1e-3}])
def test_output_cap_holds_before_auto_and_the_contract_read_the_grid(kw):
    # regression: auto's traits built the output grid before any cap was checked (numpy MemoryError, 745 GiB)
    with pytest.raises(rm.ParameterError, match="max_points"):
        coupled_clutches().simulate(1e3, 1e-8, **kw)


def test_max_points_of_two_gives_a_step_not_a_division_by_zero():
    from regmech.solvers.options import check_times
    with pytest.raises(rm.ParameterError, match=r"dt_out >= 1 s"):
        check_times(0.0, 1.0, 0.1, max_points=2)


def test_bearing_friction_refuses_a_negative_torque_table():
    # regression: a negative friction torque was accepted and drove the motion it should resist
    with pytest.raises(rm.ParameterError, match="BearingFriction 'b'.*tau_table"):
        BearingFriction("b", tau_table=[[0.0, -2.0], [1.0, -3.0]]).validate()


# -------------------------------------------------------------- non-finite values named where and what
class _RunawaySpring(TwoFlangeCompliant):
    """A softening spring whose force overflows past a deflection of 36 rad (exp(20 * 36) > 1e308)."""

    c = rm.Param(check="real", unit="N m/rad")

    def law(self, rel, rel_dot):
        import sympy
        return self.c * rel - sympy.exp(20.0 * rel)


def _runaway():
    m = rm.Model("runaway")
    f = m.add(Fixed("f"))
    k = m.add(_RunawaySpring("spring", c=100.0))
    J = m.add(Inertia("J", J=1.0, phi0=0.0, w0=0.0))
    m.connect(f.flange, k.flange_a)
    m.connect(k.flange_b, J.flange_a)
    return m


def test_non_finite_values_after_the_start_say_when_and_what():
    """Every finite parameter, a motion that ran away by t = 0.104 s: the message said "non-finite initial values at
    t=0.0 ... check parameters for NaN/inf". It names the instant, the quantity and its mass or device."""
    c = _runaway().compile()
    y, _ = c.initial_y(0.0)
    x, v, _, _, z = c.unpack(y, y)
    modes = c.modes0
    v_bad = v.copy()
    v_bad[0] = np.inf
    with pytest.raises(rm.SimulationError) as err:
        c.assemble_y(0.104, x, v_bad, z, modes)
    msg = str(err.value)
    assert "t=0.104 s" in msg and "the speed of J" in msg and "ran away" in msg and "initial" not in msg
    # a finite state whose law overflows: the device is named, with the acceleration it gives
    x_far = x.copy()
    x_far[0] = 40.0
    with pytest.raises(rm.SimulationError) as err:
        c.assemble_y(0.104, x_far, v, z, modes)
    msg = str(err.value)
    assert "t=0.104 s" in msg and "the force of spring" in msg and "from a finite state" in msg
