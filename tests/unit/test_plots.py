"""Plots an engineer puts in a report: content checks (axes, labels, units, mode strips, notes), not pixels."""

import math
import warnings

import numpy as np
import pytest

import regmech as rm

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from regmech.analysis import campbell, harmonic_response, modal, order_sweep  # noqa: E402
from regmech.plotting import default_signals  # noqa: E402


def _scene(name):
    from regmech.library import SCENES
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rm.RegularityWarning)
        return SCENES[name]()


@pytest.fixture(scope="module")
def cc():
    return _scene("coupled_clutches").simulate(1.5, dt_out=2e-3, solver="ida")


@pytest.fixture(scope="module")
def launch():
    return _scene("vehicle_launch").simulate(1.5, dt_out=5e-3, solver="ida")


def _texts(fig):
    return [t.get_text() for a in fig.axes for t in a.texts]


def _legend(ax):
    leg = ax.get_legend()
    return [t.get_text() for t in leg.get_texts()] if leg else []


# ------------------------------------------------------------------------------------- time plots
def test_default_signals_are_mass_speeds_then_device_torques(launch):
    names = default_signals(launch)
    speeds = [n for n in names if launch.unit(n) in ("rad/s", "m/s")]
    assert names[:len(speeds)] == speeds                      # speeds first
    assert names[0] == "flywheel.w" and "body.v" in speeds    # model order, masses of both kinds
    assert "clutch.tau" in names and "engine.tau" in names
    assert not any(".flange" in n or ".support" in n or ".carrier" in n for n in names)   # no flange signals


def test_default_plot_one_axis_per_unit_and_a_mode_strip_per_friction_device(launch):
    fig = launch.plot()
    labels = [a.get_ylabel() for a in fig.axes]
    assert labels[:4] == ["speed [rad/s]", "velocity [m/s]", "torque [N m]", "force [N]"]
    strips = labels[4:]
    assert strips == ["clutch", "wheel_left.road_contact", "wheel_right.road_contact"]
    clutch = fig.axes[4]
    names = [t.get_text() for t in clutch.texts]
    assert "Backward" in names and "Stuck" in names           # the modes are named in the strip
    assert fig.axes[-1].get_xlabel() == "time [s]"
    assert [t.get_text() for t in fig.axes[-1].get_legend().get_texts()] == ["Backward", "Stuck", "Forward", "Free"]
    import matplotlib.pyplot as plt
    plt.close("all")


def test_display_units_and_SI(cc, tmp_path):
    fig = cc.plot(["J1.w", "clutch1.tau"], units={"w": "rpm", "N m": "kN m"}, modes=False, path=tmp_path / "a.png")
    assert [a.get_ylabel() for a in fig.axes] == ["speed [rpm]", "torque [kN m]"]
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), cc["J1.w"] * 30 / math.pi)
    np.testing.assert_allclose(fig.axes[1].lines[0].get_ydata(), cc["clutch1.tau"] / 1e3)
    fig = cc.plot(["J1.w"], units="SI", modes=False, path=tmp_path / "b.png")
    assert fig.axes[0].get_ylabel() == "speed [rad/s]"
    assert (tmp_path / "a.png").stat().st_size > 0


def test_events_annotated_with_device_and_transition(cc, tmp_path):
    fig = cc.plot(["J1.w", "J2.w"], events="annotate", path=tmp_path / "e.png")
    listed = "\n".join(_texts(fig))
    first = cc.events[0]
    assert f"{first.component}: Free -> Backward" in listed
    numbers = [t.get_text() for t in fig.axes[0].texts]
    assert numbers[0] == "1" and len(numbers) >= 1
    # lines at every mode change on every axis
    n_instants = len({round(ev.t, 12) for ev in cc.events})
    assert len([ln for ln in fig.axes[0].lines if ln.get_linestyle() == ":"]) >= n_instants - 1
    with pytest.raises(rm.ParameterError, match="annotate"):
        cc.plot(["J1.w"], events="label")


def test_simultaneous_events_share_one_label(launch, tmp_path):
    fig = launch.plot(["body.v"], events="annotate", path=tmp_path / "l.png")
    listed = "\n".join(_texts(fig))
    assert "wheel_left.road_contact, wheel_right.road_contact: Stuck -> Forward" in listed


@pytest.mark.slow
def test_log_axis_says_which_signals_cannot_be_drawn(launch, tmp_path):
    fig = launch.plot(["body.v", "flywheel.w", "clutch.tau"], logy=True, modes=False, path=tmp_path / "g.png")
    entries = [e for a in fig.axes for e in _legend(a)]
    assert any(e.startswith("body.v (gaps where <= 0") for e in entries)            # at rest at the start
    assert "clutch.tau (<= 0 throughout: not drawn on the log axis)" in entries        # negative all along
    assert "flywheel.w" in entries                                                      # positive: no note


def test_unknown_signal_and_mode_device_refused(cc):
    with pytest.raises(rm.UnknownSignalError):
        cc.plot(["J1.ww"])
    with pytest.raises(rm.UnknownSignalError):
        cc.plot(["J1.w"], modes=["J1"])


def test_stored_result_plots_the_same_defaults(cc, tmp_path):
    back = rm.load_result(cc.save(tmp_path / "cc.mat"))
    fig = back.plot(path=tmp_path / "s.png")
    assert [a.get_ylabel() for a in fig.axes] == ["speed [rad/s]", "torque [N m]", "clutch1", "clutch2", "clutch3"]


# ------------------------------------------------------------------------- responses and Campbell
@pytest.fixture(scope="module")
def first_lin():
    return _scene("first").linearize()


def test_frequency_response_axes_carry_units_and_natural_frequencies(first_lin, tmp_path):
    lin = first_lin
    nat = modal(lin).frequencies_hz
    f_el = nat[nat > 0]
    resp = harmonic_response(lin, ["inertia1.w", "inertia3.w", "spring.tau"], np.linspace(0.1, 3 * f_el.max(), 300))
    assert resp.units == {"inertia1.w": "rad/s", "inertia3.w": "rad/s", "spring.tau": "N m"}
    assert resp.input_units == {"torque.tau": "N m"}
    np.testing.assert_allclose(resp.natural_hz, nat)
    fig = resp.plot(tmp_path / "r.png", units={"w": "rpm"})
    labels = [a.get_ylabel() for a in fig.axes]
    assert labels == ["speed amplitude\n[rpm per N m]", "torque amplitude\n[N m per N m]", "phase [deg]"]
    dashed = [ln.get_xdata()[0] for ln in fig.axes[0].lines if ln.get_linestyle() == "--"]
    np.testing.assert_allclose(sorted(dashed), sorted(f_el))
    assert any(f"{f_el[0]:.4g} Hz" in t for t in _texts(fig))


def test_response_with_an_output_the_input_does_not_reach_says_so(tmp_path):
    from regmech.components import Clutch, Inertia, Spring, Torque
    m = rm.Model("open_clutch")
    src = m.add(Torque("drive", tau=1.0))
    a, b, c = m.add(Inertia("a", J=1.0)), m.add(Inertia("b", J=1.0)), m.add(Inertia("c", J=1.0))
    cl = m.add(Clutch("clutch", mu=0.3, peak=1.1, fn_max=10.0, f_normalized=0.0))
    s = m.add(Spring("s", c=100.0))
    m.connect(src.flange, a.flange_a)
    m.connect(a.flange_b, s.flange_a)
    m.connect(s.flange_b, b.flange_a)
    m.connect(b.flange_b, cl.flange_a)
    m.connect(cl.flange_b, c.flange_a)
    lin = m.linearize(modes={"clutch": "Free"})
    fig = harmonic_response(lin, ["a.w", "c.w"], np.linspace(0.1, 5, 50)).plot(tmp_path / "z.png")
    assert "c.w (zero at every frequency: not drawn on the log axis)" in _legend(fig.axes[0])


def test_order_sweep_units_and_resonance_speeds(first_lin, tmp_path):
    lin = first_lin
    f2 = modal(lin).frequencies_hz[-1]
    speeds = np.linspace(0.2 * f2, 3 * f2, 200)                 # rev/s: order 1 and 2 cross mode 2 inside
    sw = order_sweep(lin, ["inertia3.w", "spring.tau"], [(1, 1.0, 0.0), (2, 0.5, 0.0)], speeds)
    res = sw.resonance_speeds()
    want = sorted([60 * f2 / 1, 60 * f2 / 2])
    np.testing.assert_allclose(sorted(r[3] for r in res), want)
    fig = sw.plot(tmp_path / "o.png")
    assert fig.axes[0].get_ylabel() == "inertia3.w\nspeed amplitude [rad/s]"
    assert fig.axes[1].get_ylabel() == "spring.tau\ntorque amplitude [N m]"
    assert fig.axes[-1].get_xlabel() == "engine speed [rpm]"
    assert any("order 2 meets mode" in t for t in _texts(fig))


def test_campbell_crossings_and_plot(first_lin, tmp_path):
    mr = modal(first_lin)
    f2 = float(mr.frequencies_hz[-1])
    d = mr.campbell([1, 2, 4], (100.0, 2000.0))
    got = {(o, m): n for o, m, _, n in d.crossings}
    for k in (1, 2, 4):
        n = 60 * f2 / k
        if 100 <= n <= 2000:
            assert got[(k, 2)] == pytest.approx(n, rel=1e-9)
    fig = d.plot(tmp_path / "c.png")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "engine speed [rpm]" and ax.get_ylabel() == "frequency [Hz]"
    assert any(f"mode 2: {f2:.3g} Hz" in t.get_text() for t in ax.texts)
    # natural frequencies that change with speed: crossings between grid points, by interpolation
    d2 = campbell(lambda rpm: [10.0 + rpm / 600.0], [1.0], (0.0, 3000.0))
    (o, m, fh, n), = d2.crossings
    assert n == pytest.approx(600.0 * 10.0 / 9.0, rel=1e-9) and fh == pytest.approx(n / 60)
    with pytest.raises(rm.ParameterError, match="orders"):
        campbell([10.0], [0.0])
    with pytest.raises(rm.ParameterError, match="speed_rpm"):
        campbell([10.0], [1.0], (3000.0, 100.0))


def test_campbell_against_another_shafts_speed_with_the_operating_point(tmp_path):
    """The abscissa is the speed of a shaft turning at ``ratio`` times the engine (behind a gear): engine order k
    excites f = k n_shaft / (60 ratio), resonances are read in that shaft's rpm, and the operating point is drawn."""
    d = campbell([25.0], [2.0], (0.0, 1000.0), shaft="gearbox output", ratio=0.25, operating_rpm=300.0)
    (o, m, fh, n), = d.crossings
    assert n == pytest.approx(60.0 * 25.0 * 0.25 / 2.0, rel=1e-9) and fh == pytest.approx(25.0)
    assert d.operating_point() == [(2.0, pytest.approx(2.0 * 300.0 / 15.0))]
    fig = d.plot(tmp_path / "c.png")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "gearbox output speed [rpm]"
    assert any("operating point 300 rpm" in t.get_text() for t in ax.texts)
    assert any(len(line.get_xdata()) == 2 and np.allclose(line.get_xdata(), 300.0) for line in ax.lines)
    with pytest.raises(rm.ParameterError, match="ratio"):
        campbell([25.0], [2.0], ratio=0.0)
    with pytest.raises(rm.ParameterError, match="operating_rpm"):
        campbell([25.0], [2.0], operating_rpm=float("nan"))


@pytest.mark.slow
def test_modes_cli_writes_labelled_plots_and_campbell(tmp_path, capsys):
    from regmech.analysis.cli import modes_main
    assert modes_main(["first", "--out", str(tmp_path), "--orders", "1,2", "--speed", "100:2000"]) == 0
    out = capsys.readouterr().out
    for f in ("mode_shapes.png", "response.png", "campbell.png", "campbell.csv"):
        assert (tmp_path / f).stat().st_size > 0
    assert "resonance speeds" in out
    assert modes_main(["first", "--out", str(tmp_path), "--orders", "x"]) == 2


def test_default_selection_says_what_it_left_out(tmp_path):
    res = _scene("train").simulate(0.2, dt_out=0.01, solver="ida")
    fig = res.plot(path=tmp_path / "t.png")
    entries = _legend(fig.axes[0])
    assert len(entries) == 9 and entries[-1].startswith("+2 more, e.g. car8.v, car9.v")
