"""From connection sets to *nodes*: the points of a regular mechanical system.

A node is a set of connection sets joined rigidly by masses (all flanges of
one ``Body`` share one coordinate). Each node is a mass (``bodies``), the
ground (``grounded``), a kinematically driven point (``driven_by``: flanges of
Position/Speed sources), or *massless*, which the regularity rules forbid
wherever devices meet.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..component import Body, Device, Ground
from ..ports import Flange


@dataclass(eq=False)
class Node:
    index: int
    flanges: list[Flange] = field(default_factory=list)
    bodies: list[Body] = field(default_factory=list)
    grounds: list[Ground] = field(default_factory=list)
    free_supports: list[Flange] = field(default_factory=list)   # unconnected, grounded by default
    driven_by: list[Flange] = field(default_factory=list)        # Position/Speed source flanges
    device_flanges: list[Flange] = field(default_factory=list)

    @property
    def domain(self) -> str:
        return self.flanges[0].domain

    @property
    def grounded(self) -> bool:
        return bool(self.grounds or self.free_supports)

    @property
    def ground_position(self) -> float:
        return self.grounds[0].position if self.grounds else 0.0

    @property
    def massless(self) -> bool:
        return not (self.bodies or self.grounded or self.driven_by)

    def devices(self) -> list[Device]:
        seen, out = set(), []
        for fl in self.device_flanges:
            if id(fl.component) not in seen:
                seen.add(id(fl.component))
                out.append(fl.component)
        return out

    def label(self) -> str:
        return ", ".join(f.full_name for f in self.flanges)


def build_nodes(model) -> tuple[list[Node], dict[Flange, Node]]:
    """Group the model's flanges into nodes (see module docstring)."""
    sets = model.connection_sets()
    set_of: dict[Flange, int] = {}
    for i, s in enumerate(sets):
        for fl in s:
            set_of[fl] = i
    # a body joins the connection sets of its flanges: connected components of that graph
    # (scipy's csgraph: adding edges to a networkx graph costs tens of us per body)
    a, b = [], []
    for comp in model.components.values():
        if isinstance(comp, Body):
            idx = [set_of[f] for f in comp.flange_list]
            a.extend(idx[:1] * (len(idx) - 1))
            b.extend(idx[1:])
    graph = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(len(sets), len(sets)))
    _, label = connected_components(graph, directed=False)
    groups: dict[int, list[int]] = {}
    for i, lab in enumerate(label.tolist()):      # increasing i: groups ordered by their smallest set
        groups.setdefault(lab, []).append(i)
    nodes: list[Node] = []
    node_of: dict[Flange, Node] = {}
    for cc in groups.values():
        node = Node(index=len(nodes))
        for i in cc:
            members = sets[i]
            node.flanges.extend(members)
            if len(members) == 1 and members[0].grounded_if_free:
                node.free_supports.append(members[0])
        seen_bodies: set[int] = set()      # a set, not a list scan: 10,000 masses merged rigidly share one node
        for fl in node.flanges:
            comp = fl.component
            node_of[fl] = node
            if isinstance(comp, Body):
                if id(comp) not in seen_bodies:
                    seen_bodies.add(id(comp))
                    node.bodies.append(comp)
            elif isinstance(comp, Ground):
                node.grounds.append(comp)
            elif isinstance(comp, Device):
                if fl in node.free_supports:
                    continue
                if comp.device_kind() in ("position", "speed") and fl.name == "flange":
                    node.driven_by.append(fl)
                else:
                    node.device_flanges.append(fl)
        nodes.append(node)
    return nodes, node_of
