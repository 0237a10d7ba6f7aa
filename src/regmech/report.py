"""Short readable reports of a model: ``m.check()`` and ``m.summary()``.

Both return a ``ModelReport``: its text is a few lines (whether the model is
a regular mechanical system, its components grouped by family, the states
and constraints the solvers see, the friction devices, the range of the
link frequencies); its data stay attributes (``report.families``,
``report.states``, ``report.friction_devices``, ... and, for the regularity
check, ``report.masses``, ``report.nodes`` and the rest of the
``RegularityReport``).

Families, in the order printed: ``masses`` (``Body``), ``ground``,
``sources`` (torque/force/motion sources and engines), ``elastic``
(compliant links), ``rigid`` (gears, rigid shafts), ``friction``
(clutches, brakes, one-way clutches, lossy gears), ``subsystems``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

FAMILY_ORDER = ("masses", "ground", "sources", "elastic", "rigid", "friction", "subsystems")


def family_of(comp) -> str:
    """The family a component is listed under (see module docstring)."""
    role = getattr(comp, "role", "")
    if role == "body":
        return "masses"
    if role == "ground":
        return "ground"
    if role == "subsystem":
        return "subsystems"
    kind = comp.device_kind() if hasattr(comp, "device_kind") else ""
    if getattr(comp, "is_source", False) or kind in ("position", "speed"):
        return "sources"
    if kind == "friction" or "friction" in (comp.row_kinds() if hasattr(comp, "row_kinds") else ()):
        return "friction"
    if kind == "rigid":
        return "rigid"
    return "elastic"


@dataclass(repr=False)
class ModelReport:
    """What ``m.check()`` / ``m.summary()`` found (see module docstring).

    ``ok``: the model passed the regularity check (a violation raises instead)
    and no warning was raised on the way; ``problems``: those warnings (a
    stretched spectrum), each also shown as a ``RegularityWarning``; ``families``: family -> {class name: [component
    names]}; ``states``: differential states (positions and speeds of the
    coordinates not held by constraints, and internal states of devices); ``coordinates``:
    mass coordinates (one per group of masses joined directly); ``dof`` degrees of freedom; ``constraints``: {"position": n, "speed": n,
    "friction": n} rows; ``friction_devices``: names; ``link_hz``: (lowest,
    highest) local link frequency [Hz] (``CompiledSystem.link_frequencies``),
    None without elastic links; ``regularity``: the ``RegularityReport``.
    """

    model: str
    kind: str                                   # "check" or "summary"
    ok: bool
    problems: list[str]
    families: dict[str, dict[str, list[str]]]
    states: int
    coordinates: int
    internal_states: int
    constraints: dict[str, int]
    friction_devices: list[str]
    link_hz: tuple[float, float] | None
    regularity: object = field(default=None)
    #: which path ida's callbacks take for this model: compiled (native) or Python, and why (``m.check()``)
    solver_path: str | None = None

    def __getattr__(self, name):
        # the regularity report's fields (masses, nodes, grounded_nodes, ...) read through, as m.check()
        # returned that report before
        reg = self.__dict__.get("regularity")
        if reg is not None and not name.startswith("_") and hasattr(reg, name):
            return getattr(reg, name)
        raise AttributeError(f"ModelReport has no attribute {name!r}")

    @property
    def dof(self) -> int:
        """Degrees of freedom: mass coordinates less the position constraints (gears, rigid links)."""
        return self.coordinates - self.constraints.get("position", 0)

    @property
    def n_components(self) -> int:
        return sum(len(v) for fam, classes in self.families.items() if fam != "subsystems"
                   for v in classes.values())

    def _family_text(self, names: bool) -> list[str]:
        lines = []
        for fam in FAMILY_ORDER:
            classes = self.families.get(fam)
            if not classes:
                continue
            parts = []
            for cls, members in classes.items():
                if names and len(members) <= 6:
                    parts.append(f"{cls} {', '.join(members)}")
                else:
                    parts.append(f"{len(members)} {cls}")
            lines.append(f"  {fam + ':':12s}{'; '.join(parts)}")
        return lines

    def __str__(self) -> str:
        n = len(self.problems)
        head = {"check": "regular mechanical system: OK" if self.ok else
                f"regular mechanical system with {n} problem{'s' if n != 1 else ''} (below)",
                "summary": "summary"}[self.kind]
        lines = [f"Model '{self.model}' {head} ({self.n_components} components)"]
        lines += self._family_text(names=self.kind == "summary")
        reg = self.regularity
        if reg is not None:
            lines.append(f"  {reg.masses} mass node(s), {reg.grounded_nodes} ground node(s), "
                         f"{reg.driven_nodes} driven node(s), {reg.devices} device(s)")
            lines += [f"  reduced: {note}" for note in getattr(reg, "notes", ())]
        cons = ", ".join(f"{v} {k}" for k, v in self.constraints.items() if v) or "none"
        lines.append(f"  {self.coordinates} mass coordinates, {self.dof} degrees of freedom; {self.states} states "
                     f"({self.internal_states} internal); constraint rows: {cons}")
        fr = self.friction_devices
        lines.append(f"  friction devices: {', '.join(fr[:8]) + (f' ... ({len(fr)})' if len(fr) > 8 else '') if fr else 'none'}")
        if self.link_hz is not None:
            lo, hi = self.link_hz
            lines.append(f"  link frequencies (local estimates): {lo:.3g} .. {hi:.3g} Hz (spread {hi / lo:.3g})")
        else:
            lines.append("  link frequencies: none (no elastic link)")
        if self.solver_path:
            lines.append(f"  solver path: {self.solver_path}")
        lines += [f"  problem: {p}" for p in self.problems]
        return "\n".join(lines)

    __repr__ = __str__

    def _repr_pretty_(self, p, cycle):      # IPython shows the text, not a dataclass dump
        p.text(str(self))


def model_report(model, kind: str, regularity=None, problems=()) -> ModelReport:
    """Build the report of ``model`` (compiles it, cached)."""
    compiled = model.compile()
    families: dict[str, dict[str, list[str]]] = {}
    for comp in model.components.values():
        families.setdefault(family_of(comp), {}).setdefault(type(comp).__name__, []).append(comp.name)
    for sub in model.subsystems.values():
        families.setdefault("subsystems", {}).setdefault(type(sub).__name__, []).append(sub.name)
    families = {f: families[f] for f in FAMILY_ORDER if f in families}
    st = compiled.structure
    friction = list(dict.fromkeys(r.device.name for r in st.friction))
    link_hz = None
    if compiled.Sc.shape[0]:
        w = compiled.link_frequencies()
        w = w[w > 0]
        if w.size:
            link_hz = (float(w.min()) / (2 * np.pi), float(w.max()) / (2 * np.pi))
    return ModelReport(model=model.name, kind=kind, ok=not problems, problems=list(problems), families=families,
                       states=int(compiled.ode_size()), coordinates=int(compiled.n),
                       internal_states=int(compiled.nz),
                       constraints={"position": int(compiled.mp), "speed": int(compiled.mv),
                                    "friction": int(compiled.mf)},
                       friction_devices=friction, link_hz=link_hz, regularity=regularity)
