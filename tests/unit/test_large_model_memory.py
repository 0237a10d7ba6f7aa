"""Large models stay cheap where they can (the 100,000-inertia chain): named outputs are made
per signal when read (a Result holds O(unknowns x points), never O(components x signals x points)), the
networkx graph of a model is made only when asked for, the output rows are not held twice, and the
shortcuts taken for speed (cached parameter declarations, flanges as attributes) keep the behaviour.
No wall time is asserted: what is checked is deterministic (array sizes, allocations, what exists)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import regmech as rm
from regmech.bench.hard_models import benchmark_chain as chain
from regmech.component import Param
from regmech.components import Inertia, Spring
from regmech.solvers.common import Recorder


def _array_bytes(obj) -> int:
    return sum(v.nbytes for v in vars(obj).values() if isinstance(v, np.ndarray))


@pytest.fixture(scope="module")
def chain_run():
    m = chain(400)
    res = m.simulate(0.05, 1e-4, solver="ida", rtol=1e-6)      # 501 points
    return m, res


def test_result_holds_unknowns_times_points_only(chain_run):
    m, res = chain_run
    c = m.compile()
    tr = res._traj
    points = len(res.t)
    # y (N unknowns) and the speeds' derivatives (n), the time axis, flags and modes: nothing per signal
    assert tr.Y.shape == (points, c.N)
    assert tr.YPv.shape == (points, c.n)
    assert _array_bytes(tr) <= 8 * points * (c.N + c.n + 4)
    for name in ("J0.w", "J399.phi", "sd7.tau", "sd7.power", "ground_spring.potential", "drive.flange.tau"):
        res[name]
    # reading six signals made the recipes of their five components only, and no (points x components) array
    assert set(tr._recipes) == {"J0", "J399", "sd7", "ground_spring", "drive"}
    assert _array_bytes(tr) <= 8 * points * (c.N + c.n + 4)


def test_reading_a_device_signal_allocates_per_point_not_per_component():
    m = chain(1000)
    res = m.simulate(0.02, 4e-5, solver="ida", rtol=1e-6)      # 501 points
    points = len(res.t)
    tracemalloc.start()             # the first read included: it makes the name lookups, O(components)
    try:
        for name in ("sd500.tau", "sd500.potential", "sd500.power", "sd500.flange_a.tau", "J999.a"):
            res[name]
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # eager outputs made (points x coordinates or compliant rows) matrices of x, v, a, e, e', e'', tau,
    # potentials at the first read, each 8 * 1000 * points bytes; per signal, it stays below one of them
    assert peak < 0.25 * 8 * 1000 * points, peak


def test_lazy_outputs_agree_with_the_compiled_kernels(chain_run):
    """The per-instance evaluation gives the forces the residual uses (an independent path)."""
    m, res = chain_run
    c = m.compile()
    tr = res._traj
    k = len(res.t) // 2
    y = tr.Y[k]
    x, v, z = y[c.ix], y[c.iv], y[c.iz]
    e, de, tau, dz, _ = c.kernel_outputs(x, v, z, float(res.t[k]))
    rows = {r.device.name: i for i, r in enumerate(c.structure.compliant)}
    for name in ("sd0", "sd123", "sd398", "ground_spring", "drive"):
        i = rows[name]
        assert res[f"{name}.tau"][k] == pytest.approx(tau[i], rel=1e-12, abs=1e-12)
    for name in ("sd0", "sd123", "ground_spring"):
        i = rows[name]
        assert res[f"{name}.phi_rel"][k] == pytest.approx(e[i], rel=1e-12, abs=1e-15)
        assert res[f"{name}.w_rel"][k] == pytest.approx(de[i], rel=1e-12, abs=1e-15)
        np.testing.assert_array_equal(res[f"{name}.power"], res[f"{name}.tau"] * res[f"{name}.w_rel"])
        np.testing.assert_array_equal(res[f"{name}.flange_b.tau"], res[f"{name}.tau"])
        np.testing.assert_array_equal(res[f"{name}.flange_a.tau"], -res[f"{name}.tau"])
    assert res["sd5.potential"][k] == pytest.approx(0.5 * 1e4 * e[rows["sd5"]] ** 2, rel=1e-12, abs=1e-18)
    np.testing.assert_array_equal(res["J5.kinetic"], 0.5 * m["J5"].J * res["J5.w"] ** 2)


def test_names_and_membership_without_the_full_index(chain_run):
    m, res = chain_run
    assert "sd3.flange_b.w" in res and "J7.kinetic" in res and "drive.power" in res
    assert "sd3.nothing" not in res and "nobody.w" not in res and 3 not in res
    names = res.names
    assert len(names) == len(set(names))
    # per inertia phi, w, a, kinetic; per spring-damper its 4 relative signals, power, potential and
    # angle, speed and torque at each flange, and its heat flow and accumulated heat
    assert sum(n.startswith("J7.") for n in names) == 4 and sum(n.startswith("sd3.") for n in names) == 14
    assert names == sorted(names)
    assert all(n in res for n in names[::97])
    with pytest.raises(rm.UnknownSignalError, match="J1.w"):
        res["J1.ww"]


def test_subsystem_part_signals_resolve_through_dotted_names():
    from regmech.library.vehicle import vehicle_launch
    m = vehicle_launch()
    res = m.simulate(0.05, 1e-3, solver="ida", rtol=1e-6)
    dotted = [n for n in res.names if n.count(".") >= 2 and n.rsplit(".", 1)[0] in m.components]
    assert dotted, "the vehicle has subsystem parts"
    for name in dotted[:20]:
        assert np.all(np.isfinite(res[name]))


def test_graph_is_a_view_made_on_first_use():
    m = chain(5)
    m.simulate(0.01, 1e-3, solver="ida", rtol=1e-6)
    assert m._graph is None                     # building, compiling and simulating never needed it
    g = m.graph
    comps = [n for n, d in g.nodes(data=True) if d["kind"] == "component"]
    flanges = [n for n, d in g.nodes(data=True) if d["kind"] == "flange"]
    assert sorted(comps) == sorted(m.components)
    assert len(flanges) == sum(len(c.flange_list) for c in m.components.values())
    connects = {frozenset((u, v)) for u, v, d in g.edges(data=True) if d["kind"] == "connect"}
    assert connects == {frozenset((a.full_name, b.full_name)) for a, b in m.links()}
    assert len(connects) == 2 * 4 + 1 + 2         # chain links, the drive, the end spring
    # kept up to date once made
    extra = m.add(Inertia("extra", J=1.0))
    m.connect(extra.flange_a, m["J4"].flange_b)
    assert g.has_edge("extra.flange_a", "J4.flange_b") and g.nodes["extra"]["component"] is extra


def test_connecting_a_pair_twice_is_one_link():
    m = rm.Model("twice")
    a = m.add(Inertia("a", J=1.0))
    s = m.add(Spring("s", c=1.0))
    m.connect(a.flange_b, s.flange_a)
    m.connect(s.flange_a, a.flange_b)
    assert m.links() == [(a.flange_b, s.flange_a)]
    assert [len(cs) for cs in m.connection_sets()].count(2) == 1


def test_recorder_keeps_the_asked_columns_and_never_holds_rows_twice():
    rec = Recorder(0, yp_cols=np.array([1, 3]))
    for k in range(5):
        rec.add(0.1 * k, np.arange(4.0) + k, 10 * np.arange(4.0) + k, np.zeros(0, int))
    T, Y, YP, L, MO = rec.arrays()
    assert Y.shape == (5, 4) and YP.shape == (5, 2)
    np.testing.assert_array_equal(YP[:, 0], 10 + np.arange(5.0))
    # the rows were written once into the recorder's preallocated arrays, which come back as views
    assert np.shares_memory(Y, rec.Y) and np.shares_memory(YP, rec.YP)


def test_recorder_allocates_no_rates_until_a_row_writes_them():
    # rows whose y' is filled later (the linear ODE form's deferred accelerations) leave y' unallocated; a
    # row that writes y' allocates it with the rows before zero (to be filled), growth keeps both
    rec = Recorder(0, capacity=4)
    for k in range(3):
        rec.row_buffer(3)[:] = k
        rec.commit(0.1 * k, np.zeros(0, int))
    assert rec.YP is None
    T, Y, YP, L, MO = rec.arrays()
    assert YP is None and Y.shape == (3, 3)
    y, yp = rec.row_buffers(3)
    y[:], yp[:] = 7.0, 8.0
    rec.commit(0.3, np.zeros(0, int))
    for k in range(4, 30):                               # beyond the capacity: grown
        rec.row_buffer(3)[:] = k
        rec.commit(0.1 * k, np.zeros(0, int))
    T, Y, YP, L, MO = rec.arrays()
    assert Y.shape == YP.shape == (30, 3)
    np.testing.assert_array_equal(YP[:, 0], np.r_[np.zeros(3), 8.0, np.zeros(26)])
    np.testing.assert_array_equal(Y[:, 0], np.r_[np.arange(3.0), 7.0, np.arange(4.0, 30.0)])
    rec.row_buffer(3)[1] = np.nan                        # a non-finite state is refused without rates too
    rec.commit(3.0, np.zeros(0, int))
    with pytest.raises(rm.SimulationError, match="non-finite"):
        rec.arrays()


def test_parameter_declarations_are_cached_per_class():
    Inertia("first", J=1.0)                      # caches Inertia's declarations

    class Flywheel(Inertia):
        radius = Param(0.1, check="positive", unit="m")

    f = Flywheel("fw", J=2.0)
    assert f.radius == 0.1 and "radius" in Flywheel.param_specs() and "radius" not in Inertia.param_specs()
    specs = Inertia.param_specs()
    specs.pop("J")                               # a copy: the class's declarations are untouched
    assert "J" in Inertia.param_specs()
    with pytest.raises(rm.ParameterError, match="radius"):
        Flywheel("bad", J=1.0, radius=-1.0)
    with pytest.raises(rm.ParameterError, match="must be > 0"):
        Inertia("bad", J=0.0)
    with pytest.raises(rm.ParameterError, match="smallest normal double"):
        Inertia("bad", J=1e-310)
    with pytest.raises(rm.ParameterError, match="finite"):
        Inertia("bad", J=float("nan"))


def test_flanges_are_plain_attributes():
    J = Inertia("J", J=1.0)
    assert vars(J)["flange_a"] is J.get_flange("flange_a") is J.flange_a
    from regmech.components import Wheel
    w = Wheel("w", radius=0.3, J=1.0, fn=1000.0, mu=1.0)
    for port, target in Wheel.ports.items():
        part, _, fname = target.partition(".")
        assert getattr(w, port) is w.get_flange(port) is w.parts[part].get_flange(fname)
    with pytest.raises(rm.errors.UnknownFlangeError, match="flange_c"):
        J.flange_c


def test_a_trajectory_pickled_with_all_of_y_prime_still_reads(chain_run):
    """Pickles made when the trajectory kept the whole y' (and its eager matrices) load and read."""
    from regmech.compile.outputs import Trajectory
    m, res = chain_run
    tr = res._traj
    c = m.compile()
    YP = np.zeros_like(tr.Y)
    YP[:, c.iv] = tr.YPv
    old = Trajectory.__new__(Trajectory)
    old.__setstate__({"c": c, "t": tr.t, "Y": tr.Y, "YP": YP, "left": tr.left, "modes": tr.modes, "_mat": {},
                      "_index_cache": None})
    for name in ("J3.a", "sd9.tau", "ground_spring.potential"):
        np.testing.assert_array_equal(old.get(name), res[name])
