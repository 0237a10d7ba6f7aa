"""Flanges: the connection points of components.

A rotational flange carries the across variable ``phi`` [rad] and the flow
variable ``tau`` [N m]; a translational flange ``s`` [m] and ``f`` [N].
Connecting flanges makes their across variables equal and their flows sum to
zero (Modelica semantics). ``flange.tau`` is the torque acting *on the
component* through that flange.
"""

from __future__ import annotations

from dataclasses import dataclass

ROTATIONAL = "rotational"
TRANSLATIONAL = "translational"
DOMAINS = (ROTATIONAL, TRANSLATIONAL)

#: names of (across, derivative of across, second derivative, flow) per domain
VARIABLE_NAMES = {
    ROTATIONAL: ("phi", "w", "a", "tau"),
    TRANSLATIONAL: ("s", "v", "a", "f"),
}


@dataclass(eq=False, slots=True)
class Flange:
    """One flange of one component (identity semantics: hashable by object). Slots: a model of
    100,000 components has 200,000 or more of them, and a per-instance dictionary each."""

    component: object
    name: str
    domain: str
    grounded_if_free: bool = False

    @property
    def full_name(self) -> str:
        return f"{self.component.name}.{self.name}"

    def __repr__(self) -> str:
        return f"<{self.domain} flange {self.full_name}>"

    def __getstate__(self):
        return {name: getattr(self, name) for name in self.__slots__}

    def __setstate__(self, state):
        # a dict of the fields; also the (dict, slots) pair of the default protocol and the plain dict of a
        # flange pickled before it had slots
        if isinstance(state, tuple):
            state = {**(state[0] or {}), **(state[1] or {})}
        for name, value in state.items():
            setattr(self, name, value)
