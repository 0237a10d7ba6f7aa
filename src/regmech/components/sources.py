"""Sources: prescribed torque/force and prescribed motion.

A source's ``support`` is grounded when left unconnected (MSL useSupport).
"""

from __future__ import annotations

from ..component import Device, Param
from ..ports import ROTATIONAL, TRANSLATIONAL


class Torque(Device):
    """Torque ``tau(t)`` [N m] acting on ``flange`` (and ``-tau`` on ``support``):
    MSL ``flange.tau = -tau``. ``tau`` is a number, a signal or a callable of t."""

    kind = "compliant"
    is_source = True
    #: the parameter whose signal is the device's law itself (the law is that signal and nothing else): a solver may
    #: take a sinusoidal one exactly (``solvers.expm``); read from this class only, not from a subclass
    force_signal = "tau"
    tau = Param(check="signal", unit="N m", doc="driving torque")
    flanges = (("flange", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    def rows(self):
        # e = phi_support - phi_flange, so flange.tau = -tau and power in = tau * w
        return [{"support": 1.0, "flange": -1.0}]

    def law(self, rel, rel_dot):
        return self.tau


class Force(Device):
    """Force ``f(t)`` [N] acting on ``flange`` (and ``-f`` on ``support``)."""

    kind = "compliant"
    is_source = True
    force_signal = "f"          # as Torque.force_signal
    f = Param(check="signal", unit="N", doc="driving force")
    flanges = (("flange", TRANSLATIONAL), ("support", TRANSLATIONAL, True))
    default_domain = TRANSLATIONAL
    rel_names = {TRANSLATIONAL: (None, None, None, "f")}

    def rows(self):
        return [{"support": 1.0, "flange": -1.0}]

    def law(self, rel, rel_dot):
        return self.f


class _Prescribed(Device):
    is_source = True
    flanges = (("flange", None), ("support", None, True))

    def rows(self):
        return [{"flange": 1.0, "support": -1.0}]


class Position(_Prescribed):
    """Prescribed angle ``phi(flange) - phi(support) = phi_ref(t)`` [rad];
    the signal's first two derivatives must exist. Its value and its slope
    must be continuous inside the run: a jump, or a corner of a Ramp or Table,
    would make the prescribed speed jump (an impulse) and is refused when the
    run starts; a jump in its second derivative is a time event.
    Exports ``tau`` = torque needed on the support side (``flange.tau = tau``)."""

    kind = "position"
    phi_ref = Param(check="signal", unit="rad", doc="reference angle")
    rel_names = {ROTATIONAL: ("phi", "w", "a", "tau")}
    ref_param = "phi_ref"


class Speed(_Prescribed):
    """Prescribed speed ``w(flange) - w(support) = w_ref(t)`` [rad/s]; ``w_ref`` must be
    continuous inside the run (a Step would need an impulse and is refused when the run
    starts; a Ramp's corners are time events)."""

    kind = "speed"
    w_ref = Param(check="signal", unit="rad/s", doc="reference speed")
    rel_names = {ROTATIONAL: ("phi", "w", "a", "tau")}
    ref_param = "w_ref"


class LinearPosition(_Prescribed):
    """Prescribed position ``s_ref(t)`` [m] of a translational flange."""

    kind = "position"
    default_domain = TRANSLATIONAL
    s_ref = Param(check="signal", unit="m", doc="reference position")
    rel_names = {TRANSLATIONAL: ("s", "v", "a", "f")}
    ref_param = "s_ref"


class LinearSpeed(_Prescribed):
    """Prescribed velocity ``v_ref(t)`` [m/s] of a translational flange."""

    kind = "speed"
    default_domain = TRANSLATIONAL
    v_ref = Param(check="signal", unit="m/s", doc="reference velocity")
    rel_names = {TRANSLATIONAL: ("s", "v", "a", "f")}
    ref_param = "v_ref"
