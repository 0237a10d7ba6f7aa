"""The rules of the regular mechanical system (REFERENCES.md [003]), as checks.

1. Devices (massless) join masses or the ground. A node where devices meet
   without a mass is accepted where its motion is determinate (Modelica's
   rule): a coordinate that a rigid row makes dependent, or a node of
   compliant devices whose force balance gives its speed (a spring and a
   damper in series: the node's position becomes a first-order state); the
   reduction is listed in the report's ``notes``. Otherwise it is an error
   naming the devices.
   The three wrong schematizations of the paper get their own explanation:
   a massless spring under a load, a friction device on the massless end of
   an elastic shaft, dampers meeting at a massless point.
2. (warning, in ``compile``) a stretched spectrum: a few masses or links far
   from the rest, better replaced by ground or rigid links.
3. Variable-structure devices (clutch, brake, friction contact) have a mass
   (or the ground) on each side in every state.

Also caught here: dangling flanges (under-determined), a node both grounded
and driven, a node driven twice.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import ModelError, RegularityError
from .topology import Node, build_nodes


@dataclass
class RegularityReport:
    nodes: list[Node]
    masses: int
    grounded_nodes: int
    driven_nodes: int
    devices: int
    notes: list[str] = field(default_factory=list)

    def __str__(self) -> str:
        lines = [f"regular mechanical system: {self.masses} mass node(s), {self.grounded_nodes} ground node(s), "
                 f"{self.driven_nodes} driven node(s), {self.devices} device(s)"]
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def _names(devices) -> str:
    return ", ".join(f"{type(d).__name__} '{d.name}'" for d in devices)


def _massless_node_message(node: Node) -> str:
    devs = node.devices()
    kinds = {d.name: d.device_kind() for d in devs}
    sources = [d for d in devs if d.is_source]
    friction = [d for d in devs if kinds[d.name] == "friction"]
    compliant = [d for d in devs if kinds[d.name] == "compliant" and not d.is_source]
    where = f"at the point joining {node.label()}"
    if friction:
        others = [d for d in devs if d not in friction]
        return (f"variable-structure device {_names(friction)} has no mass on one side ({where}); "
                f"the regular-system rules (Position 3) need a mass on each side of a clutch/brake in every state, "
                f"otherwise its closing cannot be computed"
                + (f" (it hangs on the massless end of {_names(others)})" if others else "")
                + ". Fix: insert an Inertia (or Mass) between them, even a small one, e.g. the shaft's own inertia.")
    if compliant and all(type(d).__name__ == "Damper" for d in compliant) and not sources and len(compliant) >= 2:
        return (f"dampers {_names(compliant)} meet at a massless point ({where}); the point's motion has no "
                f"dynamics of its own and cannot be solved for systematically. Fix: add a mass at that point, "
                f"or replace the dampers by one equivalent damper.")
    if sources and compliant:
        return (f"{_names(compliant)} carries the load of {_names(sources)} at a massless point ({where}): "
                f"without a mass the link has no dynamics and its torque always equals the load (any mass, however "
                f"small, gives an oscillation with peak twice the load). Fix: insert an Inertia (or Mass) at that point.")
    return (f"devices {_names(devs)} are joined directly with no mass between them ({where}); devices must join "
            f"masses or the ground (regular-system rule 1). Fix: insert an Inertia (or Mass) at that point, "
            f"or merge the devices into one.")


def _determinate_note(node: Node) -> str | None:
    """The reduction of a massless node that Modelica accepts, or None when the rules refuse it.

    * A node with a rigid row (a gear, a rigid shaft, a rolling wheel): its coordinate becomes a dependent
      (dummy) coordinate of that constraint, and its force balance gives the constraint force.
    * A node of compliant devices only (springs, dampers, sources; a Maxwell element): its position becomes a
      first-order state, its speed an algebraic unknown of its force balance. Whether that balance determines
      the speed (a damper at the node) is decided by the compiler (``compile.massless``), which refuses the
      node with the message of ``_massless_node_message`` otherwise.

    A friction device on a massless node without a rigid row stays refused (Position 3: its closing needs an
    inertia on each side, which a rigid row reflects onto the node)."""
    devs = node.devices()
    kinds = [d.device_kind() for d in devs]
    rigid = [d for d in devs if "rigid" in d.row_kinds() or d.device_kind() in ("rigid", "position")]
    if rigid:
        # a clutch there sees the inertia the rigid row reflects onto the point (Position 3 holds through it)
        return (f"massless point {node.label()}: its motion follows from the constraint of {_names(rigid)} "
                f"(a dependent coordinate; its force balance gives the constraint force)")
    if "friction" in kinds:
        return None
    if all(k == "compliant" for k in kinds):
        return (f"massless point {node.label()}: first-order node between {_names(devs)} (its position a state, "
                f"its speed from the balance of their forces)")
    return None


def check_model(model) -> RegularityReport:
    """Raise ``RegularityError``/``ModelError`` for every violation found (all listed)."""
    if not model.components:
        raise ModelError(f"Model '{model.name}' is empty; add components before simulating")
    nodes, _ = build_nodes(model)
    problems: list[str] = []
    dangling: list[str] = []
    regular: list[str] = []
    notes: list[str] = []
    for node in nodes:
        if len(node.driven_by) > 1:
            problems.append(f"the point {node.label()} is driven by several motion sources "
                            f"({_names(f.component for f in node.driven_by)}); keep one")
        if node.driven_by and node.grounded:
            problems.append(f"{_names(f.component for f in node.driven_by)} drives a point that is fixed to the "
                            f"ground ({node.label()}); connect its flange to a mass or remove the Fixed")
        if not node.massless:
            continue
        if len(node.device_flanges) <= 1:
            if node.device_flanges:
                fl = node.device_flanges[0]
                dangling.append(f"flange {fl.full_name} of {type(fl.component).__name__} '{fl.component.name}' is not "
                                f"connected, which leaves the model under-determined; connect it to a mass "
                                f"(Inertia/Mass) or to a Fixed")
            continue
        note = _determinate_note(node)
        if note is None:
            regular.append(_massless_node_message(node))
        else:
            notes.append(note)
    if problems or dangling:
        raise ModelError("; ".join(problems + dangling + regular))
    if regular:
        raise RegularityError("\n".join(regular))
    devices = {id(fl.component) for n in nodes for fl in n.device_flanges + n.driven_by}
    return RegularityReport(
        nodes=nodes,
        masses=sum(1 for n in nodes if n.bodies and not n.grounded and not n.driven_by),
        grounded_nodes=sum(1 for n in nodes if n.grounded),
        driven_nodes=sum(1 for n in nodes if n.driven_by),
        devices=len(devices),
        notes=notes,
    )
