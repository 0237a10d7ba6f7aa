"""Switching surfaces of piecewise-smooth laws as event functions (contacts of backlash, gaps, stops).

A device with a kink or a switch in its law (``Backlash``: no torque inside the play, a spring
outside it) states its surfaces ``g(e, de)`` (``Device.switching_surfaces``; ``compile`` evaluates
them for all instances at once, ``CompiledSystem.surface_values``). Here they become event functions
that every solver watches like the friction ones, so the integration stops at the kink and restarts
on the other branch: no step straddles it, and the accuracy at contact no longer depends on how the
step control happens to cross it.

Each function is ``side_k * g_k`` with ``side_k`` the sign of ``g_k`` at the start of the segment,
crossing zero downwards when the state leaves that side (one direction, as the friction functions:
an event function changing sign at the restart would fire again at once). At a crossing the crossed
sides are flipped (the new segment starts on the surface, on the new side by construction, whatever
the round-off of ``g`` there), and each device whose state changed gives an ``Event`` of its
``switching_kind``: "contact" (state codes: 0 open, the surface's code in contact, e.g. +1 / -1 for
the upper / lower side of a backlash or an end stop) or "limit" (a controller's output at its upper
limit +1, at its lower one -1, between them 0).
"""

from __future__ import annotations

import numpy as np

#: the kind of the ``Event`` of a change of contact state
CONTACT = "contact"


class SurfaceSet:
    """The switching surfaces of a compiled system with the side each one is on."""

    def __init__(self, c):
        self.c = c
        self.n_events = c.n_surf
        self.owner = c.surface_owner
        self.sides = np.ones(self.n_events)
        self._flipped = None        # sides set by a crossing, kept by the next ``begin``
        self._running = False       # a segment of the current run has begun (``begin``)
        devices = {}
        for k, (name, code) in enumerate(self.owner):
            devices.setdefault(name, []).append((k, code))
        self._devices = devices
        self._kinds = getattr(c, "surface_kinds", {})
        #: surfaces of latch states (``compile.reads``): after a crossing the latch moves and its surface jumps
        #: back below zero, so the next segment takes their side from their sign, not from the flip
        self._latch = np.zeros(self.n_events, bool)
        self._latch[np.asarray(getattr(c, "latch_surfaces", ()), int)] = True

    def reset(self):
        """Forget a crossing of a previous run (a run starts from the surfaces' signs alone)."""
        self._flipped = None
        self._running = False
        self.c.surface_sides = None      # branch states (``compile.reads``) take the signs themselves

    def begin(self, t, y) -> list[tuple[str, int, int, str]]:
        """Set the sides at the start of a segment from the surfaces' signs at ``(t, y)``; the surfaces
        just crossed keep the side ``cross`` gave them (on the surface, the sign of g is round-off).

        Returns ``(device, old, new, kind)`` for each device whose contact state these sides change against
        the previous segment's (none at the run's first segment): a surface that reached zero at the instant
        of another event (a friction event, a breakpoint, another surface's crossing) and starts the next
        segment a round-off past it changed its device's state there, and the drivers record it as an
        ``Event`` instead of letting it pass silently."""
        g = self.c.surface_values(t, y)
        sides = np.where(g < 0.0, -1.0, 1.0)
        if self._flipped is not None:
            idx, kept = self._flipped
            on = ~self._latch[idx]
            sides[idx[on]] = kept[on]
            self._flipped = None
        if self._latch.any():
            # a latch's surface back below zero after its crossing is no change of its own (``cross`` reported it)
            sides_cmp = sides.copy()
            sides_cmp[self._latch] = self.sides[self._latch]
        else:
            sides_cmp = sides
        changes = self._changes(self.sides, sides_cmp) if self._running else []
        self._running = True
        self.sides = sides
        self.c.surface_sides = sides
        return changes

    def event_values(self, t, y):
        """``side * g`` per surface: positive until the state leaves the side it started the segment on."""
        return self.sides * self.c.surface_values(t, y)

    def states(self, sides=None) -> dict:
        """Contact state per device: the code of its first surface on the positive side, else 0."""
        sides = self.sides if sides is None else sides
        out = {}
        for name, entries in self._devices.items():
            out[name] = next((code for k, code in entries if sides[k] > 0), 0)
        return out

    def cross(self, crossed) -> list[tuple[str, int, int, str]]:
        """Flip the sides of the surfaces ``crossed`` (indices); returns ``(device, old, new, "contact")``
        for each device whose contact state changed."""
        idx = np.asarray(crossed, dtype=int)
        if idx.size == 0:
            return []
        sides = self.sides.copy()
        sides[idx] = -sides[idx]
        changes = self._changes(self.sides, sides)
        self.sides = sides
        self.c.surface_sides = sides     # the restart's branch states read the new sides (``compile.reads``)
        self._flipped = (idx, sides[idx])
        return changes

    def _changes(self, old_sides, new_sides) -> list[tuple[str, int, int, str]]:
        """``(device, old, new, kind)`` for each device whose contact state differs between the two sides."""
        if np.array_equal(old_sides, new_sides):
            return []
        before, after = self.states(old_sides), self.states(new_sides)
        return [(name, before[name], after[name], self._kinds.get(name, CONTACT)) for name in before
                if before[name] != after[name]]


class Guards:
    """The event functions a solver watches: the friction set's (``2 mf``) followed by the surfaces'."""

    def __init__(self, friction, surfaces):
        self.fr = friction
        self.surfaces = surfaces
        self.n_friction = friction.n_events if friction is not None else 0
        self.n_events = self.n_friction + (surfaces.n_events if surfaces is not None else 0)

    def event_values(self, t, y, yp, modes):
        if self.surfaces is None:
            return self.fr.event_values(t, y, yp, modes)
        g = self.surfaces.event_values(t, y)
        if self.fr is None or not self.n_friction:
            return g
        return np.concatenate([self.fr.event_values(t, y, yp, modes), g])

    def split(self, crossed):
        """``crossed`` (a 0/nonzero array over all functions) -> (the friction part, the crossed surfaces)."""
        crossed = np.asarray(crossed)
        return crossed[:self.n_friction], np.nonzero(crossed[self.n_friction:])[0]


def guards_for(c):
    """The ``Guards`` of an attached compiled system, or None when it has no event functions."""
    fr = c.friction
    surf = c.__dict__.get("surfaces")
    nf = fr.n_events if fr is not None else 0
    ns = surf.n_events if surf is not None else 0
    if nf + ns == 0:
        return None
    return Guards(fr, surf)


__all__ = ["CONTACT", "SurfaceSet", "Guards", "guards_for"]
