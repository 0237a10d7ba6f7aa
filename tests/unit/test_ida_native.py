"""The native IDA path (``solver="ida", native=True``: SUNDIALS through ctypes, numba callbacks) against the
scikit-sundae path on the same models: same solver and tolerances, answers within the tolerance of each
other and of an accurate reference; models it cannot serve run the usual path and say why."""

from __future__ import annotations

import numpy as np
import pytest

import regmech as rm
from regmech.bench.hard_models import benchmark_chain as chain
from regmech.components import Damper, Fixed, IdealGear, Inertia, Position, Speed, SpringDamper, Torque
from regmech.library import coupled_clutches, first
from regmech.signals import Constant, Function, Ramp, Sine, Step, Table

pytest.importorskip("numba")
from regmech.solvers import ida_native  # noqa: E402

if isinstance(ida_native.libraries(), str):
    pytest.skip(f"native IDA not available: {ida_native.libraries()}", allow_module_level=True)


def mixed_inputs():
    """Every signal type the kernels evaluate, with time events (Step, Ramp corners) and a gear."""
    m = rm.Model("mixed_inputs")
    f = m.add(Fixed("fixed"))
    J = [m.add(Inertia(f"J{i}", J=0.5 + 0.25 * i, w0=None if i == 1 else 0.3 * i)) for i in range(4)]
    m.add(IdealGear("gear", ratio=2.5))
    m.connect(J[0].flange_b, m.components["gear"].flange_a)
    m.connect(m.components["gear"].flange_b, J[1].flange_a)
    m.connect(m.components["gear"].support, f.flange)
    for k, (a, b) in enumerate(((1, 2), (2, 3))):
        s = m.add(SpringDamper(f"sd{k}", c=400.0 * (k + 1), d=2.0))
        m.connect(J[a].flange_b, s.flange_a)
        m.connect(s.flange_b, J[b].flange_a)
    ground = m.add(Damper("ground_damper", d=3.0))
    m.connect(J[3].flange_b, ground.flange_a)
    m.connect(ground.flange_b, f.flange)
    sources = [Sine(amplitude=4.0, freq_hz=3.0, phase=0.3, offset=0.5, start_time=0.1),
               Step(height=-2.0, start_time=0.35, offset=0.2), Ramp(height=3.0, duration=0.4, start_time=0.2),
               Constant(-0.7)]
    for i, sig in enumerate(sources):
        t = m.add(Torque(f"tq{i}", tau=sig))
        m.connect(t.flange, J[i].flange_a)
    return m


def _compare(m, t_end, rtol, **kw):
    a = m.simulate(t_end, dt_out=1e-2, solver="ida", rtol=rtol, native=True, **kw)
    b = m.simulate(t_end, dt_out=1e-2, solver="ida", rtol=rtol, native=False, **kw)
    assert a.stats.extra.get("native") is True
    assert "native" not in b.stats.extra
    np.testing.assert_array_equal(a.t, b.t)
    return a, b


@pytest.mark.parametrize("build, t_end", [(first, 1.0), (lambda: chain(10), 1.0), (mixed_inputs, 1.0),
                                          (lambda: chain(60), 0.5)])
def test_native_agrees_with_the_python_path_and_a_tight_reference(build, t_end):
    m = build()
    ref = m.simulate(t_end, dt_out=1e-2, solver="ida", rtol=1e-11, atol=1e-13, native=False)
    a, b = _compare(m, t_end, 1e-7)
    names = [n for n in ref.names if n.endswith((".w", ".phi"))]
    for name in names:
        scale = max(1e-12, float(np.ptp(ref[name])))
        err_native = float(np.abs(a[name] - ref[name]).max()) / scale
        err_python = float(np.abs(b[name] - ref[name]).max()) / scale
        # the same method at the same tolerance: errors of the same size (round-off moves the steps)
        assert err_native <= max(10.0 * err_python, 1e-6), (name, err_native, err_python)
    assert a.stats.segments == b.stats.segments


def test_native_band_solver_with_a_reordering():
    m = chain(60)
    c = m.compile()
    from regmech.solvers.ida import choose_linsolver
    assert choose_linsolver(c)[0] == "band"
    a, b = _compare(m, 0.3, 1e-8)
    speeds = np.array([b[f"J{i}.w"] for i in range(60)])
    scale = float(np.ptp(speeds))          # relative to the range of the speeds (the far end barely moves)
    for i in (0, 10, 30, 59):
        assert float(np.abs(a[f"J{i}.w"] - b[f"J{i}.w"]).max()) <= 1e-5 * scale


def test_native_segments_at_time_events_use_left_limits():
    """A Step and a Ramp split the run; at each segment end the signals are read as left limits."""
    m = mixed_inputs()
    a, b = _compare(m, 1.0, 1e-9, atol=1e-11)
    assert a.stats.segments == b.stats.segments >= 4
    for name in ("J0.w", "J3.phi", "sd1.tau"):
        scale = max(1e-12, float(np.ptp(b[name])))
        assert float(np.abs(a[name] - b[name]).max()) <= 1e-6 * scale


def _speed_dependent_clutch():
    m = coupled_clutches()
    m.components["clutch1"].mu_table = [[0.0, 0.5], [5.0, 0.3]]
    return m


@pytest.mark.parametrize("model, reason", [
    (_speed_dependent_clutch, "speed-dependent"),
    (lambda: chain(3, tau=Function(lambda t: np.sin(t))), "Function"),
])
def test_models_the_native_path_cannot_serve_run_the_usual_path_and_say_why(model, reason):
    m = model()
    res = m.simulate(0.5, dt_out=0.05, solver="ida", native=True)
    note = res.stats.extra.get("native")
    assert isinstance(note, str) and note.startswith("not used") and reason in note
    plain = m.simulate(0.5, dt_out=0.05, solver="ida", native=False)
    np.testing.assert_array_equal(res["J1.w" if "J1.w" in res.names else "J0.w"],
                                  plain["J1.w" if "J1.w" in plain.names else "J0.w"])


@pytest.mark.parametrize("source", [
    lambda: Speed("src", w_ref=Sine(amplitude=1.0, freq_hz=1.0, start_time=0.1)),
    lambda: Speed("src", w_ref=Ramp(height=2.0, duration=0.3, start_time=0.2)),
    lambda: Speed("src", w_ref=Table([(0.0, 0.0), (0.2, 1.0), (0.5, -0.5), (0.8, 0.0)])),
    lambda: Position("src", phi_ref=Sine(amplitude=0.2, freq_hz=2.0, phase=np.pi / 2, offset=-0.2)),
], ids=["speed_sine", "speed_ramp", "speed_table", "position_sine"])
def test_position_and_speed_sources_run_native_with_the_python_path_s_answer(source):
    """A prescribed motion's reference and its derivatives (the index reduction's rows) evaluated by the
    compiled residual: the answer of the Python path, and the source's torque too."""
    m = chain(3)
    src = m.add(source())
    m.connect(src.flange, m.components["J2"].flange_b)
    a, b = _compare(m, 1.0, 1e-9)
    for name in ("J0.w", "J2.w", "src.tau"):
        np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-6 * max(np.ptp(b[name]), 1e-3))


def test_a_reference_the_kernels_cannot_evaluate_is_named_and_time_limits_are_read():
    m = chain(3)
    m.add(Speed("spd", w_ref=Function(lambda t: np.sin(t))))
    m.connect(m.components["spd"].flange, m.components["J2"].flange_b)
    res = m.simulate(0.2, dt_out=0.05, solver="ida", native=True)
    assert "Position/Speed source has a Function reference" in res.stats.extra["native"]
    # the residual kernels read the clock (``_native_kernels._past_deadline``)
    res = chain(3).simulate(0.2, dt_out=0.05, solver="ida", native=True, timeout_s=60)
    assert res.stats.extra["native"] is True


def test_a_native_run_past_its_time_limit_raises_simulation_timeout():
    m = chain(10)
    m.simulate(0.05, dt_out=0.01, solver="ida", native=True)          # kernels loaded before the limit starts
    with pytest.raises(rm.SimulationTimeout, match="timed out"):
        # about 2e7 steps at rtol 1e-10: far longer than the limit of 0.2 s on any machine
        m.simulate(2000.0, dt_out=1.0, solver="ida", native=True, rtol=1e-10, max_steps=10**9, timeout_s=0.2)


def test_native_failure_is_a_simulation_error_naming_the_model():
    """IDA's own failure (too many steps) comes back as the usual SimulationError."""
    m = chain(10)
    with pytest.raises(rm.SimulationError, match="max_steps=3"):
        m.simulate(1.0, dt_out=0.5, solver="ida", native=True, max_steps=3)


def test_native_flag_is_checked():
    with pytest.raises(rm.ParameterError, match="native"):
        first().simulate(0.1, solver="ida", native="yes")


def test_a_work_budget_still_counts_every_residual_call():
    """The budget of the fuzz and hard-case benches wraps the compiled residual: neither the native path nor
    the shortcut callback of the usual path may go around it."""
    from regmech.bench.guard import WorkBudgetExceeded, work_budget
    m = chain(5)
    for native in (False, True):
        with pytest.raises(WorkBudgetExceeded):
            with work_budget(m, 40):
                m.simulate(0.5, dt_out=0.1, solver="ida", native=native)


def test_native_reports_ida_s_own_step_count():
    """The native path reads IDA's accepted steps (IDAGetNumSteps); the usual path counts attempts, which
    are at least as many (accepted + rejected) on the same model and tolerances."""
    m = chain(5, tau=Sine(amplitude=1.0, freq_hz=2.0))
    native = m.simulate(1.0, 0.01, solver="ida", rtol=1e-6, native=True)
    usual = m.simulate(1.0, 0.01, solver="ida", rtol=1e-6, native=False)
    assert native.stats.extra["native"] is True
    assert native.stats.extra["steps_are_attempts"] is False and "attempts" not in str(native.stats)
    assert 10 < native.stats.steps <= usual.stats.steps <= 2 * native.stats.steps


def test_eligibility_is_kept_with_the_compiled_model_but_a_wrapped_residual_is_seen(monkeypatch):
    m = coupled_clutches()
    c = m.compile()
    calls = []
    real = ida_native._eligible
    monkeypatch.setattr(ida_native, "_eligible", lambda c, ls: calls.append(ls) or real(c, ls))
    assert ida_native.eligible(c, "dense") is None and ida_native.eligible(c, "dense") is None
    assert calls == ["dense"]
    c.__dict__["residual"] = c.residual               # a work budget wraps the residual on the instance
    assert "wrapped" in ida_native.eligible(c, "dense")
    del c.__dict__["residual"]
    laws = ida_native.friction_laws(c.friction)
    assert ida_native.friction_laws(c.friction) is laws
    m["clutch1"].fn_max = 2.0 * m["clutch1"].fn_max    # a change: a new compiled model, decided anew
    assert m.compile() is not c
    assert ida_native.eligible(m.compile(), "dense") is None and calls == ["dense", "dense"]


def test_the_call_that_loads_the_compiled_kernels_says_so_once(monkeypatch):
    """numba's import and the kernels' load (6 s the first time on a machine, compiling them into the cache) were
    inside the first run's time: the README's demo printed "First: simulated 1.0 s in 6604 ms". They are now loaded
    before any run's clock starts and reported beside it, by the call that paid them only."""
    lib = ida_native.libraries()
    monkeypatch.setattr(lib, "load_s", 1.23, raising=False)
    monkeypatch.setattr(lib, "reported", False, raising=False)
    first_call = first().simulate(0.1, dt_out=0.01)
    assert first_call.stats.extra["native_load_s"] == 1.23
    assert "ms (+ 1.2 s loading the compiled kernels, once per process)" in str(first_call.stats)
    again = first().simulate(0.1, dt_out=0.01, solver="ida")
    assert "native_load_s" not in again.stats.extra and "loading" not in str(again.stats)
