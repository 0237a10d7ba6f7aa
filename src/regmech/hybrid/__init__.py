"""The hybrid layer: the mode logic of friction and loss elements, shared by every solver.

It sits between ``compile`` (the DAE and its friction rows in given modes) and ``solvers`` (which
drive time): the event functions the solvers watch (``events``), the iteration of the modes at an
event (``logic``) with the holding torques of stuck devices (``holding``) and the driving sides
of lossy gears (``gears``), the guard against chattering (``chatter``), and the switching surfaces
of piecewise laws (contacts of backlash, gaps and stops, ``surfaces``). Components state only
their laws (kinetic torque, capacities, the equation of each mode); this layer decides with them.
"""

from __future__ import annotations

from .chatter import ChatterGuard
from .friction_set import FrictionSet
from .surfaces import CONTACT, Guards, SurfaceSet, guards_for


def attach(compiled):
    """Give a compiled system's friction rows their mode logic (once); returns ``compiled``.

    The solvers call it when a run starts; ``compile`` itself knows nothing of this layer.

    ``compiled.friction`` becomes a ``FrictionSet`` sharing the rows' state, so the residual
    (``compile``) and the mode logic (``settle``) see the same modes and driving sides.
    """
    rows = compiled.friction
    if rows is not None and not isinstance(rows, FrictionSet):
        compiled.friction = FrictionSet.from_rows(rows)
    if getattr(compiled, "n_surf", 0) and compiled.__dict__.get("surfaces") is None:
        # the switching surfaces of piecewise laws (contacts), located as events (``surfaces``)
        compiled.surfaces = SurfaceSet(compiled)
    return compiled


__all__ = ["ChatterGuard", "FrictionSet", "SurfaceSet", "Guards", "CONTACT", "attach", "guards_for"]
