"""expm's linearity check samples the laws where their kinks are: at and between the device's own
parameter values (a play centred away from zero, an end stop's travel limits)."""

import pytest

import regmech as rm
from regmech.components import Backlash, ElastoBacklash, Fixed, Inertia, Spring
from regmech.components.stops import EndStop
from regmech.errors import SimulationError
from regmech.solvers.expm import nonlinear_components


def _one(dev):
    m = rm.Model("k")
    J = m.add(Inertia("J", J=1.0, phi0=0.0, w0=1.0))
    f = m.add(Fixed("f"))
    m.add(dev)
    names = [fl.name for fl in dev.flange_list]
    m.connect(J.flange_a, dev.get_flange(names[0]))
    if "support" not in names:
        m.connect(dev.get_flange(names[1]), f.flange)
    return m


@pytest.mark.parametrize("dev", [
    Backlash("bl", c=2487.0, b=1e-3, phi_rel0=0.8255),                    # was taken for a linear spring
    ElastoBacklash("bl", c=2487.0, d=0.035, b=1e-3, phi_rel0=0.8255),
    EndStop("stop", lower=-0.8261, upper=-0.825, c=2487.0, d=0.035),      # a fuzz model (drivetrain families)
], ids=lambda d: type(d).__name__)
def test_a_narrow_kink_away_from_zero_is_nonlinear(dev):
    m = _one(dev)
    assert nonlinear_components(m.compile(), 0.0, 1.0) == [f"{type(dev).__name__} '{dev.name}'"]
    with pytest.raises(SimulationError, match=type(dev).__name__):
        m.simulate(0.1, solver="expm")


def test_a_spring_with_an_offset_stays_linear():
    m = _one(Spring("s", c=100.0, phi_rel0=0.8255))
    assert nonlinear_components(m.compile(), 0.0, 1.0) == []
