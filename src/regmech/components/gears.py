"""Ideal gears."""

from __future__ import annotations

from ..component import Device, Param
from ..ports import ROTATIONAL


class IdealGear(Device):
    """Ideal gear (MSL IdealGear): ``phi_a - phi_s = ratio * (phi_b - phi_s)``,
    ``0 = ratio * flange_a.tau + flange_b.tau``, ``support`` grounded when left free.

    Device coordinate ``e = phi_a - ratio*phi_b + (ratio-1)*phi_support = 0``;
    its constraint force is ``flange_a.tau`` (exported as ``tau``).
    """

    kind = "rigid"
    ratio = Param(check="nonzero", unit="1", doc="transmission ratio phi_a/phi_b")
    flanges = (("flange_a", ROTATIONAL), ("flange_b", ROTATIONAL), ("support", ROTATIONAL, True))
    rel_names = {ROTATIONAL: (None, None, None, "tau")}

    def rows(self):
        r = self.ratio
        return [{"flange_a": 1.0, "flange_b": -r, "support": r - 1.0}]
