"""Scene reduction: model only what the requested outputs need.

Each pass takes a model and returns a new one (the original is never
changed) plus a list of ``Action``s saying what was done and why, or what
was refused and why. Passes (all optional):

``drop_disengaged``
    friction devices whose normal force is <= 0 over the whole scene
    transmit nothing: removed (certain only for signals whose bound over
    the interval is known: Constant, Step, Ramp, Table, Pulse, a Sine of
    zero amplitude).
``prune``
    components that cannot influence the outputs: influence travels from
    node to node through any device, but not through the ground or a
    kinematically driven point (their motion does not depend on loads).
    A free branch that still loads a kept node through a device is kept.
``merge_rigid``
    masses joined by a rigid ``Shaft`` become one body (the shaft is
    removed and the masses connected directly); a leaf inertia behind an
    ``IdealGear`` is reflected into the mass on the other side,
    ``J_a += J_b / ratio^2``, and its signals are reconstructed
    (``w_b = w_a / ratio``).
``rigidify``
    a linear link (Spring, SpringDamper, Shaft) whose local frequency
    ``sqrt(c (1/m_a + 1/m_b)) / 2 pi`` is above ``factor * band_hz`` becomes a
    rigid Shaft; a stiff link whose mode lies inside the band is refused.
``ground_heavy``
    a mass ``ratio`` times heavier than every mass it is linked to moves
    (nearly) at its start speed: it is driven at that constant speed (or
    fixed when at rest); its reaction torque is no longer felt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..component import Body, Device, Ground
from ..errors import ModelError
from ..signals import Constant, Pulse, Ramp, Sine, Step, Table
from .topology import build_nodes


@dataclass
class Action:
    kind: str               # pass name
    components: list[str]
    reason: str
    applied: bool = True

    def __str__(self):
        verb = "" if self.applied else "refused: "
        return f"[{self.kind}] {verb}{', '.join(self.components)}: {self.reason}"


@dataclass
class OutputMap:
    """How a requested output of the full model is read from the reduced one."""

    source: str
    scale: float = 1.0


@dataclass
class Reduction:
    model: object
    actions: list[Action] = field(default_factory=list)
    outputs: dict[str, OutputMap] = field(default_factory=dict)


# -- cloning ------------------------------------------------------------------
def clone_component(comp, **changes):
    """A fresh component with the same parameters (subsystem parts keep their dotted names)."""
    values = dict(comp._values)
    values.update(changes)
    new = type(comp)("clone", domain=comp.domain, **values)
    new.name = comp.name
    return new


class ModelEditor:
    """Rebuild a model with components removed, replaced, re-parameterised or added."""

    def __init__(self, model):
        self.src = model
        self.removed: set[str] = set()
        self.changes: dict[str, dict] = {}
        self.replaced: dict[str, object] = {}
        self.extra: list = []
        self.extra_links: list[tuple[str, str]] = []
        self.dropped_links: set[frozenset] = set()

    def build(self, name=None):
        from ..model import Model
        m = Model(name or self.src.name)
        new_of = {}
        for cname, comp in self.src.components.items():
            if cname in self.removed:
                continue
            new = self.replaced.get(cname) or clone_component(comp, **self.changes.get(cname, {}))
            new.model = None
            m.components[new.name] = new
            new.model = m
            new_of[cname] = new
        for comp in self.extra:
            m.add(comp)
        for fa, fb in self.src.links():
            u, v = fa.full_name, fb.full_name
            (cu, fu), (cv, fv) = u.rsplit(".", 1), v.rsplit(".", 1)
            if cu in new_of and cv in new_of and frozenset((u, v)) not in self.dropped_links:
                try:
                    m.connect(new_of[cu].get_flange(fu), new_of[cv].get_flange(fv))
                except ModelError:
                    pass
        for a, b in self.extra_links:
            m.connect(a, b)
        return m


# -- helpers ----------------------------------------------------------------------
def signal_upper_bound(sig, t0, t1):
    """An upper bound of the signal on [t0, t1], or None when not known for certain."""
    if isinstance(sig, Constant):
        return sig.value_
    if isinstance(sig, Pulse) and sig.count_breakpoints(t0, t1) > 1000:
        return sig.bounds()[1]          # many pulses: their height bounds them (listing them could hang)
    if isinstance(sig, (Step, Ramp, Table, Pulse)):
        pts = [t0, t1] + [b for b in sig.breakpoints(t0, t1) if t0 <= b <= t1]
        return max(max(sig.value(p), sig.value(p, left=True)) for p in pts)
    if isinstance(sig, Sine):
        return sig.offset + abs(sig.amplitude) if sig.amplitude != 0 else sig.offset
    return None


def output_component(model, name: str):
    """The component an output name belongs to (longest matching prefix)."""
    parts = name.split(".")
    for k in range(len(parts) - 1, 0, -1):
        cand = ".".join(parts[:k])
        if cand in model.components:
            return cand
    raise ModelError(f"output '{name}' names no component of model '{model.name}'")


def node_graph(model):
    """Nodes as graph vertices, devices as hyper-edges (one edge per pair of its nodes)."""
    nodes, node_of = build_nodes(model)
    import networkx as nx

    g = nx.MultiGraph()
    g.add_nodes_from(n.index for n in nodes)
    for comp in model.components.values():
        if isinstance(comp, Device):
            idx = sorted({node_of[fl].index for fl in comp.flange_list})
            for i in idx[1:]:
                g.add_edge(idx[0], i, device=comp.name)
    return nodes, node_of, g


# -- passes -----------------------------------------------------------------------
def drop_disengaged(model, t0, t1, keep=()):
    from ..components.friction import FrictionDevice
    ed, actions = ModelEditor(model), []
    for comp in model.components.values():
        if not isinstance(comp, FrictionDevice) or comp.name in keep:
            continue
        sig = comp._values.get("f_normalized", comp._values.get("fn"))
        if sig is None:
            continue
        ub = signal_upper_bound(sig, t0, t1)
        if ub is not None and ub <= 0.0:
            ed.removed.add(comp.name)
            actions.append(Action("drop_disengaged", [comp.name],
                                  f"normal force <= 0 on [{t0:g}, {t1:g}] s: it transmits nothing"))
        elif ub is None and not comp.name.startswith("_"):
            pass
    return (ed.build() if ed.removed else model), actions


def prune(model, outputs):
    nodes, node_of, g = node_graph(model)
    keep_nodes: set[int] = set()
    seeds = set()
    for name in outputs:
        comp = model.components[output_component(model, name)]
        seeds |= {node_of[fl].index for fl in comp.flange_list}
    # influence does not travel through ground or driven points
    blocked = {n.index for n in nodes if n.grounded or n.driven_by}
    frontier = list(seeds)
    while frontier:
        k = frontier.pop()
        if k in keep_nodes:
            continue
        keep_nodes.add(k)
        if k in blocked and k not in seeds:
            continue
        frontier.extend(nb for nb in g.neighbors(k) if nb not in keep_nodes)
    ed, removed = ModelEditor(model), []
    for comp in model.components.values():
        idx = {node_of[fl].index for fl in comp.flange_list}
        touches = bool(idx & keep_nodes)
        if isinstance(comp, Device):
            # a device is needed when it acts on a kept node that is free to move
            live = {i for i in idx & keep_nodes if i not in blocked or i in seeds}
            if not live and comp.name not in {output_component(model, o) for o in outputs}:
                touches = False
        if not touches:
            ed.removed.add(comp.name)
            removed.append(comp.name)
    if not removed:
        return model, []
    return ed.build(), [Action("prune", removed, "cannot influence the requested outputs (no path through a "
                                                  "device to them that avoids the ground and driven points)")]


def merge_rigid(model, outputs):
    from ..components.elastic import Shaft
    from ..components.gears import IdealGear
    nodes, node_of, g = node_graph(model)
    needed = {output_component(model, o) for o in outputs}
    ed, actions, maps = ModelEditor(model), [], {}
    for comp in model.components.values():
        if not (isinstance(comp, Shaft) and comp.device_kind() == "rigid") or comp.name in needed:
            continue
        na, nb = node_of[comp.flange_a], node_of[comp.flange_b]
        if not (na.bodies and nb.bodies) or na.driven_by or nb.driven_by:
            continue
        ed.removed.add(comp.name)
        ed.extra_links.append((f"{na.bodies[0].name}.{na.bodies[0].flange_list[0].name}",
                               f"{nb.bodies[0].name}.{nb.bodies[0].flange_list[0].name}"))
        actions.append(Action("merge_rigid", [na.bodies[0].name, comp.name, nb.bodies[0].name],
                              "masses joined by a rigid shaft become one body"))
    for comp in model.components.values():
        if not isinstance(comp, IdealGear) or comp.name in needed or comp.name in ed.removed:
            continue
        na, nb = node_of[comp.flange_a], node_of[comp.flange_b]
        if not node_of[comp.support].grounded:
            continue
        for near, far, factor in ((na, nb, 1.0 / comp.ratio), (nb, na, comp.ratio)):
            far_devs = [d for d in far.devices() if d is not comp]
            if far_devs or far.driven_by or far.grounded or len(far.bodies) != 1 or not near.bodies:
                continue
            if far.bodies[0].name in needed and False:
                continue
            jb, ja = far.bodies[0], near.bodies[0]
            if jb.start[0] is not None or jb.start[1] is not None:
                continue          # its start values would fix the near side: keep the gear
            # kinetic energy 1/2 J_b w_b^2 with w_b = factor * w_a
            new_J = ja.mass + jb.mass * factor**2
            ed.changes.setdefault(ja.name, {})[ja.mass_param] = new_J
            ed.removed |= {comp.name, jb.name}
            pn, wn, an, _ = jb.var_names()
            for v in (pn, wn, an):
                maps[f"{jb.name}.{v}"] = OutputMap(f"{ja.name}.{v}", factor)
            maps[f"{jb.name}.kinetic"] = OutputMap(f"{ja.name}.kinetic", 0.0)
            actions.append(Action("merge_rigid", [jb.name, comp.name, ja.name],
                                  f"leaf inertia behind a gear reflected: J = {ja.mass:g} + {jb.mass:g} x "
                                  f"{factor:g}^2 = {new_J:g}"))
            break
    if not actions:
        return model, [], {}
    return ed.build(), actions, maps


LINEAR_LINKS = {"Spring": "c", "SpringDamper": "c", "Shaft": "stiffness"}


def rigidify(model, outputs, band_hz, factor=10.0):
    from ..components.elastic import Shaft
    nodes, node_of, g = node_graph(model)
    needed = {output_component(model, o) for o in outputs}
    ed, actions = ModelEditor(model), []
    import networkx as nx

    groups = nx.utils.UnionFind()
    for comp in model.components.values():
        if isinstance(comp, Device) and comp.device_kind() == "rigid":
            idx = [node_of[fl].index for fl in comp.flange_list]
            groups.union(*idx)
    stiff = []
    for comp in model.components.values():
        pname = LINEAR_LINKS.get(type(comp).__name__)
        if pname is None or comp._values.get(pname) is None:
            continue
        na, nb = node_of[comp.flange_a], node_of[comp.flange_b]

        def inv(n):
            return 0.0 if (n.grounded or n.driven_by) else 1.0 / sum(b.mass for b in n.bodies)
        w2 = comp._values[pname] * (inv(na) + inv(nb))
        stiff.append((comp, na, nb, math.sqrt(w2) / (2 * math.pi)))
    if not stiff:
        return model, []
    median_f = float(np.median([f for *_, f in stiff]))
    for comp, na, nb, f_hz in stiff:
        if f_hz >= factor * band_hz:
            if groups[na.index] == groups[nb.index]:
                actions.append(Action("rigidify", [comp.name], "would close a loop of rigid links", False))
                continue
            if comp.name in needed and any(o.startswith(comp.name + ".phi_rel") or o.startswith(comp.name + ".s_rel")
                                           for o in outputs):
                actions.append(Action("rigidify", [comp.name], "its deflection is a requested output", False))
                continue
            groups.union(na.index, nb.index)
            ed.replaced[comp.name] = _rigid_shaft(comp)
            note = ""
            twist = _start_deflection(model, na, nb)
            if abs(twist) > 0.0:
                # a pre-deflected link made rigid: the start positions beyond it follow the rigid link
                for b in nb.bodies:
                    if b.start[0] is not None:
                        ed.changes.setdefault(b.name, {})[b.start_params[0]] = None
                note = f"; its start deflection {twist:.4g} is dropped (positions beyond it shift by that much)"
            actions.append(Action("rigidify", [comp.name],
                                  f"local mode at {f_hz:.4g} Hz >= {factor:g} x band {band_hz:g} Hz: rigid link"
                                  + note))
        elif f_hz >= band_hz:
            actions.append(Action("rigidify", [comp.name],
                                  f"its local mode {f_hz:.4g} Hz ({f_hz / median_f:.3g} x the median link) lies "
                                  f"inside {factor:g} x the band of {band_hz:g} Hz: making it rigid would change "
                                  f"the answer in the band", False))
    if not ed.replaced:
        return model, actions
    return ed.build(), actions


def _start_position(model, node) -> float:
    """Position of ``node`` at the model's consistent start (the ground's position on the ground)."""
    c = model.compile()
    k = c.structure.node_coord[node.index]
    if k is None:
        return node.ground_position
    y, _ = c.initial_y(0.0)
    return float(y[c.ix][k])


def _start_deflection(model, na, nb) -> float:
    """x_b - x_a at the model's consistent start (0 when either side is the ground)."""
    return _start_position(model, nb) - _start_position(model, na)


def _rigid_shaft(comp):
    from ..components.elastic import Shaft
    new = Shaft("tmp", stiffness=None, domain=comp.domain)
    new.name = comp.name
    return new


def ground_heavy(model, outputs, ratio=1e4):
    from ..components.sources import LinearSpeed, Speed
    from ..components.inertial import Fixed
    nodes, node_of, g = node_graph(model)
    needed = {output_component(model, o) for o in outputs}
    ed, actions = ModelEditor(model), []
    for node in nodes:
        if not node.bodies or node.grounded or node.driven_by:
            continue
        m = sum(b.mass for b in node.bodies)
        neigh = [nodes[nb] for nb in g.neighbors(node.index)]
        neigh_m = [sum(b.mass for b in n.bodies) for n in neigh if n.bodies and not n.grounded]
        if not neigh_m or m < ratio * max(neigh_m):
            continue
        body = node.bodies[0]
        w0 = body.start[1] or 0.0
        if body.name in needed:
            actions.append(Action("ground_heavy", [body.name], "heavy, but its own motion is a requested output",
                                  False))
            continue
        fl = body.flange_list[0]
        if w0 == 0.0:
            # grounded where it starts: a Fixed at 0 would contradict a start position (an error) and
            # change the deflection of the links to it
            fixed = Fixed(f"ground_{abs(hash(body.name)) % 10**8}", domain=body.domain,
                          phi0=_start_position(model, node))
            ed.extra.append(fixed)
            ed.extra_links.append((fl.full_name, f"{fixed.name}.flange"))
            what = "fixed (it starts at rest)"
        else:
            cls = Speed if body.domain == "rotational" else LinearSpeed
            src = cls(f"drive_{abs(hash(body.name)) % 10**8}", **{cls.ref_param: w0})
            ed.extra.append(src)
            ed.extra_links.append((fl.full_name, f"{src.name}.flange"))
            what = f"driven at its start speed {w0:g}"
        actions.append(Action("ground_heavy", [body.name],
                              f"{m / max(neigh_m):.3g} times heavier than its neighbours: {what}"))
    if not ed.extra:
        return model, actions
    return ed.build(), actions
