"""Masses and the ground: ``Inertia``, ``Mass``, ``Fixed``."""

from __future__ import annotations

from ..component import Body, Ground, Param
from ..ports import ROTATIONAL, TRANSLATIONAL


class Inertia(Body):
    """Rotating inertia: ``J * a = flange_a.tau + flange_b.tau``.

    J [kg m^2] > 0; ``phi0`` [rad] and ``w0`` [rad/s] are start values, fixed
    when given (None lets initialisation choose them consistently, guess 0).
    Signals: ``phi``, ``w``, ``a``.
    """

    J = Param(check="positive", unit="kg m^2", doc="moment of inertia")
    phi0 = Param(None, optional=True, unit="rad", doc="start angle (fixed when given)")
    w0 = Param(None, optional=True, unit="rad/s", doc="start speed (fixed when given)")
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL))
    mass_param = "J"
    start_params = ("phi0", "w0")


class Mass(Body):
    """Sliding mass: ``m * a = flange_a.f + flange_b.f``.

    m [kg] > 0; ``s0`` [m], ``v0`` [m/s] start values (fixed when given).
    Signals: ``s``, ``v``, ``a``.
    """

    m = Param(check="positive", unit="kg", doc="mass")
    s0 = Param(None, optional=True, unit="m", doc="start position (fixed when given)")
    v0 = Param(None, optional=True, unit="m/s", doc="start velocity (fixed when given)")
    flanges = (("flange_a", TRANSLATIONAL), ("flange_b", TRANSLATIONAL))
    default_domain = TRANSLATIONAL
    mass_param = "m"
    start_params = ("s0", "v0")


class Fixed(Ground):
    """The ground: its ``flange`` stays at ``phi0`` [rad] (or ``s0`` [m] with
    ``domain="translational"``)."""

    phi0 = Param(0.0, unit="rad", doc="position of the flange (m when translational)")
    flanges = (("flange", None),)
    position_param = "phi0"

    def __init__(self, name, *, domain=None, s0=None, **params):
        if s0 is not None:
            params.setdefault("phi0", s0)
            domain = domain or TRANSLATIONAL
        super().__init__(name, domain=domain, **params)
