"""m.draw(): the dynamic scheme. Content checks: blocks, symbols, names, ground, layout order; not pixels."""

import builtins
import warnings

import pytest

import regmech as rm
from regmech.components import Clutch, Damper, Fixed, IdealGear, Inertia, Spring, Torque

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from regmech.draw import Scheme, device_symbol  # noqa: E402
from regmech.library import SCENES  # noqa: E402


def _texts(fig):
    return [t.get_text() for a in fig.axes for t in a.texts]


def _build(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rm.RegularityWarning)
        return SCENES[name]()


def test_coupled_clutches_reads_left_to_right_along_the_power_path(tmp_path):
    m = _build("coupled_clutches")
    fig = m.draw(path=tmp_path / "cc.png")
    assert (tmp_path / "cc.png").stat().st_size > 0
    sch = Scheme(m)
    pos = sch.layout()
    x = {k.split(":")[-1]: p[0] for k, p in pos.items() if k.startswith("dev:")}
    masses = {sch.nodes[k]["label"].split("\n")[0]: p[0] for k, p in pos.items() if k.startswith("mass:")}
    order = [x["torque"], masses["J1"], x["clutch1"], masses["J2"], x["clutch2"], masses["J3"], x["clutch3"],
             masses["J4"]]
    assert order == sorted(order) and len(set(order)) == len(order)
    texts = _texts(fig)
    for name in ("J1\nJ=1 kg m²", "clutch1", "clutch2", "clutch3", "torque", "friction device (red)", "ground"):
        assert name in texts
    assert "4 masses, 4 devices, 3 with friction" in fig.axes[0].get_title(loc="left")
    red = [t for t in fig.axes[0].texts if t.get_text().startswith("clutch")]
    assert all(matplotlib.colors.to_hex(t.get_color()) == "#c44e52" for t in red)     # friction marked


def test_symbols_by_kind_and_ground():
    m = rm.Model("kinds")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=1.0))
    a, b, c = (m.add(Inertia(n, J=1.0)) for n in "abc")
    gear = m.add(IdealGear("gear", ratio=3.0))
    spring = m.add(Spring("spring", c=100.0))
    damper = m.add(Damper("damper", d=2.0))
    clutch = m.add(Clutch("clutch", mu=0.3, peak=1.1, fn_max=10.0, f_normalized=1.0))
    m.connect(drive.flange, a.flange_a)
    m.connect(a.flange_b, gear.flange_a)
    m.connect(gear.flange_b, b.flange_a)
    m.connect(b.flange_b, spring.flange_a)
    m.connect(spring.flange_b, c.flange_a)
    m.connect(c.flange_b, clutch.flange_a)
    m.connect(clutch.flange_b, fixed.flange)
    m.connect(damper.flange_a, b.flange_a)
    m.connect(damper.flange_b, fixed.flange)
    kinds = {d.name: device_symbol(d) for d in (drive, gear, spring, damper, clutch)}
    assert kinds == {"drive": "source", "gear": "gear", "spring": "spring", "damper": "damper",
                     "clutch": "friction"}
    sch = Scheme(m)
    assert {k for k in sch.grounded} >= {"dev:drive", "dev:gear", "dev:damper", "dev:clutch"}   # free supports too
    assert "dev:spring" not in sch.grounded
    fig = m.draw()
    texts = _texts(fig)
    assert "gear\ni=3" in texts and "spring\nc=100" in texts and "damper\nd=2" in texts
    assert {"spring (c)", "damper (d)", "gear set (ratio i)", "source: torque, force"} <= set(texts)
    import matplotlib.pyplot as plt
    plt.close("all")


def test_a_massless_point_is_drawn_not_refused():
    m = rm.Model("not_regular")
    a, b = m.add(Inertia("a", J=1.0)), m.add(Inertia("b", J=1.0))
    s1, s2 = m.add(Spring("s1", c=1.0)), m.add(Spring("s2", c=1.0))
    m.connect(a.flange_b, s1.flange_a)
    m.connect(s1.flange_b, s2.flange_a)            # the springs meet without a mass
    m.connect(s2.flange_b, b.flange_a)
    fig = m.draw()
    assert "massless\npoint" in _texts(fig)


@pytest.mark.slow
@pytest.mark.parametrize("scene", sorted(SCENES))
def test_every_library_scene_draws(scene, tmp_path):
    m = _build(scene)
    fig = m.draw(path=tmp_path / f"{scene}.png")
    sch = Scheme(m)
    sch.layout()
    assert set(sch.pos) == set(sch.nodes)                      # everything placed
    n_dev = sum(1 for c in m.components.values() if c.role == "device")
    assert f"{n_dev} devices" in fig.axes[0].get_title(loc="left")
    if len(m.components) <= 50:                                # names readable: every device labelled
        texts = "\n".join(_texts(fig))
        assert all(c.name in texts for c in m.components.values() if c.role == "device")


def test_long_scheme_wraps_into_rows():
    m = _build("train")
    sch = Scheme(m)
    pos = sch.layout(max_columns=8)
    assert max(p[0] for p in pos.values()) <= 7
    assert len({round(p[1]) for p in pos.values()}) > 3


def test_cli_draw(tmp_path, capsys):
    from regmech.cli import main
    assert main(["draw", "first", "--out", str(tmp_path / "f.png")]) == 0
    assert (tmp_path / "f.png").stat().st_size > 0
    assert "scheme written to" in capsys.readouterr().out
    assert main(["draw", "no_such_scene"]) == 2


def test_clear_error_without_matplotlib(monkeypatch):
    real = builtins.__import__

    def fake(name, *args, **kw):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError("no matplotlib")
        return real(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", fake)
    with pytest.raises(rm.RegmechError, match=r"pip install 'regmech\[plot\]'"):
        _build("first").draw()
