"""``Model``: components plus acausal connections, viewed as a networkx graph.

A model keeps its components (by name) and its connections (pairs of
flanges). ``Model.graph`` is the networkx view of them, made on first use:
one node per component (``kind="component"``) and one per flange
(``kind="flange"``, named ``"comp.flange"``); ``owns`` edges join a
component to its flanges, ``connect`` edges join connected flanges. A
connection set is a connected component of the flange nodes under
``connect`` edges (across variables equal, flows sum to zero). Building
and compiling never make the graph: for 100,000 components it cost about
4 s and 400 MB (three graph nodes with attribute dictionaries per component).
"""

from __future__ import annotations

from typing import Iterable

from .component import Component, Subsystem
from .errors import ModelError, UnknownFlangeError
from .ports import Flange


class Model:
    """A regular mechanical system under construction.

    >>> m = Model("demo")
    >>> J1 = m.add(Inertia("J1", J=1.0))
    >>> m.connect(a.flange, J1.flange_a)
    """

    def __init__(self, name: str = "model"):
        self.name = name
        self.components: dict[str, Component] = {}
        self.subsystems: dict[str, Subsystem] = {}
        #: connections (flange, flange) in the order made; a pair connected twice appears twice (harmless
        #: for the connection sets; ``links()`` lists it once)
        self._links: list[tuple[Flange, Flange]] = []
        self._graph = None
        self._compiled = None

    @property
    def graph(self):
        """The networkx graph of components and flanges (see the module docstring), made on first use
        and kept up to date by ``add`` and ``connect`` from then on."""
        if self._graph is None:
            import networkx as nx
            g = nx.Graph()
            for comp in self.components.values():
                self._graph_add(g, comp)
            for fa, fb in self._links:
                g.add_edge(fa.full_name, fb.full_name, kind="connect")
            self._graph = g
        return self._graph

    @staticmethod
    def _graph_add(g, component) -> None:
        g.add_node(component.name, kind="component", component=component)
        for fl in component.flange_list:
            g.add_node(fl.full_name, kind="flange", flange=fl)
            g.add_edge(component.name, fl.full_name, kind="owns")

    def links(self) -> list[tuple[Flange, Flange]]:
        """The connections, as (flange, flange) pairs in the order they were made (a pair connected
        twice is listed once)."""
        seen, out = set(), []
        for fa, fb in self._links:
            key = frozenset((fa, fb))
            if key not in seen:
                seen.add(key)
                out.append((fa, fb))
        return out

    def __setstate__(self, state):
        if "graph" in state:          # a model pickled before the graph became a view
            g = state.pop("graph")
            state["_links"] = [(g.nodes[u]["flange"], g.nodes[v]["flange"])
                               for u, v, d in g.edges(data=True) if d["kind"] == "connect"]
            state["_graph"] = None
        self.__dict__.update(state)

    # -- assembly -----------------------------------------------------------
    def add(self, component: Component) -> Component:
        """Add a component; returns it, so ``J1 = m.add(Inertia(...))`` reads well."""
        if not isinstance(component, Component):
            raise ModelError(f"Model '{self.name}': add() takes a regmech component, got {component!r}")
        if component.model is self:
            raise ModelError(f"{type(component).__name__} '{component.name}' was added to model '{self.name}' twice; add it once")
        if component.model is not None:
            raise ModelError(f"{type(component).__name__} '{component.name}' already belongs to model "
                             f"'{component.model.name}'; create a new instance for model '{self.name}'")
        if component.name in self.components or component.name in self.subsystems:
            raise ModelError(f"Model '{self.name}' already has a component named '{component.name}'; "
                             f"give each component a unique name")
        if isinstance(component, Subsystem):
            return self._add_subsystem(component)
        component.model = self
        self.components[component.name] = component
        if self._graph is not None:
            self._graph_add(self._graph, component)
        self._invalidate()
        return component

    def _add_subsystem(self, sub: Subsystem) -> Subsystem:
        sub.model = self
        self.subsystems[sub.name] = sub
        for local, part in sub.parts.items():
            part.name = f"{sub.name}.{local}"    # parts are named through their subsystem
            self.add(part)
        for a, b in sub.links:
            self.connect(a, b)
        return sub

    def add_all(self, components: Iterable[Component]) -> list[Component]:
        return [self.add(c) for c in components]

    def _resolve(self, flange) -> Flange:
        if isinstance(flange, str):
            comp_name, _, fname = flange.rpartition(".")
            owner = self.components.get(comp_name) or self.subsystems.get(comp_name)
            if owner is None:
                raise ModelError(f"Model '{self.name}' has no component '{comp_name}' (in connect('{flange}'))")
            flange = owner.get_flange(fname)
        if not isinstance(flange, Flange):
            raise ModelError(f"connect() takes flanges such as J1.flange_a or 'J1.flange_a', got {flange!r}")
        owner = flange.component
        if owner.model is not self:
            raise ModelError(f"flange {flange.full_name} belongs to a component that is not in model "
                             f"'{self.name}'; add {type(owner).__name__} '{owner.name}' first")
        return flange

    def connect(self, a, b) -> None:
        """Connect two flanges: across variables equal, flows sum to zero."""
        fa, fb = self._resolve(a), self._resolve(b)
        if fa is fb:
            raise ModelError(f"connect({fa.full_name}, {fb.full_name}): a flange cannot be connected to itself")
        if fa.domain != fb.domain:
            raise ModelError(
                f"connect({fa.full_name}, {fb.full_name}): cannot connect a {fa.domain} flange to a "
                f"{fb.domain} flange; use a device that converts between them (e.g. a Wheel or an ideal rack)")
        self._links.append((fa, fb))
        if self._graph is not None:
            self._graph.add_edge(fa.full_name, fb.full_name, kind="connect")
        self._invalidate()

    def __getitem__(self, name: str) -> Component:
        comp = self.components.get(name) or self.subsystems.get(name)
        if comp is None:
            raise ModelError(f"Model '{self.name}' has no component '{name}'")
        return comp

    def __contains__(self, name: str) -> bool:
        return name in self.components or name in self.subsystems

    def __iter__(self):
        return iter(self.components.values())

    def __len__(self) -> int:
        return len(self.components)

    def connection_sets(self) -> list[list[Flange]]:
        """Flanges grouped by connection set (unconnected flanges alone), in the order the
        components were added (scipy's connected components: networkx's are ~10x slower
        for 10,000-component models)."""
        import numpy as np
        import scipy.sparse as sp
        from scipy.sparse.csgraph import connected_components

        flanges = [fl for comp in self.components.values() for fl in comp.flange_list]
        index = {fl: i for i, fl in enumerate(flanges)}        # flanges hash by identity
        pairs = [(index[a], index[b]) for a, b in self._links]
        n = len(flanges)
        if pairs:
            a, b = np.array(pairs).T
            adj = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
        else:
            adj = sp.coo_matrix((n, n))
        _, label = connected_components(adj, directed=False)
        groups: dict[int, list[Flange]] = {}
        for i, lab in enumerate(label):
            groups.setdefault(int(lab), []).append(flanges[i])
        return list(groups.values())

    def _invalidate(self) -> None:
        self._compiled = None

    # -- analysis and simulation ---------------------------------------------
    def check(self, warn: bool = True):
        """Regularity check: raises ``RegularityError`` / ``ModelError`` naming every violation, warns
        (``RegularityWarning``) about a stretched spectrum; returns a short ``report.ModelReport`` (its
        text: OK, components by family, states, constraints, friction devices, link frequencies, whether
        ida's callbacks are compiled for it or which device keeps them in Python; its data as attributes). ``warn=False``: the regularity rules only, no compilation (the
        ``RegularityReport``)."""
        from .structure.regularity import check_model
        regularity = check_model(self)
        if not warn:
            return regularity
        import warnings
        from .report import model_report
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self.compile().warn_spectrum()
        for w in caught:             # shown as before, and kept in the report
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        report = model_report(self, "check", regularity, [str(w.message) for w in caught])
        from .solvers.ida_native import solver_path
        report.solver_path = solver_path(self.compile())
        return report

    def summary(self):
        """What the model is made of, in a few lines (a ``report.ModelReport``): components by family,
        states, constraints, friction devices, the range of the link frequencies. Checks regularity
        on the way (raises as ``check`` does)."""
        from .report import model_report
        from .structure.regularity import check_model
        return model_report(self, "summary", check_model(self))

    def compile(self):
        """Build (once, cached until the model changes) the compiled system."""
        if self._compiled is None:
            from .compile.system import compile_model
            # cross-parameter checks again: a parameter assigned after construction (e.g. a clutch's
            # mu_table) was checked on its own only
            for comp in self.components.values():
                comp.validate()
            self._compiled = compile_model(self)
        return self._compiled

    def draw(self, path=None, ax=None, max_columns: int = 18, figsize=None, title=None):
        """Draw the dynamic scheme: masses as blocks, the devices between them by kind with their names
        (spring, damper, gear, source, friction devices in red), the ground, laid out left to right along
        the power path (``regmech.draw``). Needs matplotlib (``pip install 'regmech[plot]'``). Returns the
        figure; ``path`` writes it (PNG, SVG, PDF by the suffix)."""
        from .draw import draw_model
        return draw_model(self, path=path, ax=ax, max_columns=max_columns, figsize=figsize, title=title)

    def simulate(self, t_end: float, dt_out: float | None = None, solver: str = "auto", *,
                 accuracy: float | None = None, t_start: float = 0.0, **options):
        """Simulate from ``t_start`` to ``t_end``; returns a ``Result``.

        ``dt_out`` is the output interval (default: 500 points). ``solver``:
        ``"auto"`` (default) picks the method from the model's structure and
        meets ``accuracy`` (default 1e-3: the bound of the estimated global
        error of every state signal relative to the range of the signals of
        its kind; ``AccuracyError`` when it cannot); or one of
        ``regmech.solvers.SOLVERS``, which runs exactly as asked with its
        options (``rtol``, ``atol``, ``h``, ...), under the same contract when
        ``accuracy`` is given (see ``regmech.solvers.accuracy``); ``timeout_s`` [s] bounds
        a run's wall time (``SimulationTimeout`` beyond it); ``max_points``
        (default 1,000,000) caps the number of output points; ``progress``:
        True shows a progress bar (simulated time, solver, step attempts,
        events) on stderr, False none, None (default) one after 3 s when
        stderr is a terminal (an interactive session; never under pytest).
        """
        from .solvers import simulate
        return simulate(self, t_end=t_end, dt_out=dt_out, solver=solver, accuracy=accuracy, t_start=t_start,
                        **options)

    def linearize(self, t: float = 0.0, modes=None, at=None, inputs=None, outputs=None, **options):
        """The model linearised about an operating point.

        A model of masses and devices without internal states, asked without ``inputs``/``outputs``: the
        structural-matrix form ``M q'' + B q' + C q = W u`` (``compile.linear.linearize``; ``options``: e.g.
        ``sparse=True``). A model with internal states (electric machines, controllers, causal blocks), or
        one asked with ``inputs=[...]``/``outputs=[...]`` or ``form="state_space"``: the first-order
        ``StateSpace`` ``x' = A x + B u``, ``y = C x + D u`` (``compile.statespace``) with named ``states``,
        ``inputs`` (``"<device>.<signal parameter>"``, e.g. ``"load.tau"``; default all) and ``outputs``
        (``"J.w"``, ``"pi.y"``, ``"spring.phi_rel"``; default the states); both forms give the same poles
        where both apply.

        ``at``: None (the scene's start values at ``t``), a dict of mass positions and speeds, a tuple
        ``(x, v)``, or a ``Result`` of a simulation of this model (also one loaded from a file): then the
        operating point is that run at time ``t`` [s] -- the positions and speeds of every mass and the
        friction modes the run had there (``res.at``; at an event instant, those after the event), made
        consistent with the constraints of those modes. ``modes`` given with a result overrides the
        run's mode of the devices it names. The scene's start values play no part then, so a clutch
        that is Stuck at ``t`` in the run is linearised Stuck even if the scene starts it Free.
        ``modes`` without ``at``: the start values, and when the start speeds contradict the modes asked
        for (two start speeds across a clutch asked Stuck) the closest speeds that obey them (a
        mass-weighted impulse, momentum kept), with a ``UserWarning`` naming the conflict.
        """
        from .compile.linear import linearize
        from .result import Result
        c = self.compile()
        form = options.pop("form", None)
        if inputs is not None or outputs is not None or c.nz or form == "state_space":
            return _state_space(c, t, modes, at, inputs, outputs)
        if isinstance(at, Result):
            modes, at = _run_point(c, at, t, modes)
        elif at is None and modes is not None:
            at = _start_point(c, t, modes)
        return linearize(c, t=t, modes=modes, at=at, **options)

    def __repr__(self) -> str:
        return f"Model({self.name!r}, {len(self.components)} components)"


def _run_point(c, res, t, modes):
    """(friction modes per row, (x, v)) of compiled system ``c`` at time ``t`` of run ``res``.

    The positions ``x`` and speeds ``v`` of the coordinates are the run's mass signals interpolated
    at ``t`` (``res.at``), projected onto the constraints of the modes (linear interpolation between
    two consistent output points keeps linear constraints; the projection removes the solver's
    tolerance-sized residue). The modes are the run's ``<device>.mode`` signals at ``t`` (the value after
    an event at an event instant), overridden by ``modes`` (a dict device -> mode, or one mode per
    friction row)."""
    import numpy as np
    from .compile.linear import _mode_code, _resolve_modes
    from .errors import ParameterError

    st = c.structure
    t = float(t)
    t0, t1 = float(res.t[0]), float(res.t[-1])
    if not (np.isfinite(t) and t0 <= t <= t1):
        raise ParameterError(f"linearize(at=res, t={t!r}): t must lie in the run of model '{res.model_name}', "
                             f"[{t0:g}, {t1:g}] s; simulate further or pick a time inside it")
    x, v = np.zeros(c.n), np.zeros(c.n)
    for k, node in enumerate(st.coord_node):
        body = node.bodies[0]
        pn, wn, _, _ = body.var_names()
        for arr, name in ((x, f"{body.name}.{pn}"), (v, f"{body.name}.{wn}")):
            if name not in res:
                raise ParameterError(f"linearize(at=res): the result (model '{res.model_name}') has no signal "
                                     f"'{name}' of model '{c.model.name}'; pass a result of a run of this model "
                                     f"(saved with all its signals)")
            arr[k] = res.at(name, t)
    run_modes = np.asarray(c.modes0, int).copy()
    for j, row in enumerate(st.friction):
        name = f"{row.device.name}.mode"
        if name not in res:
            raise ParameterError(f"linearize(at=res): the result has no signal '{name}' (the mode of friction "
                                 f"device '{row.device.name}'); pass a result of a run of model '{c.model.name}'")
        run_modes[j] = int(round(res.at(name, t)))
    traj = getattr(res, "_traj", None)
    if getattr(traj, "c", None) is c and getattr(traj, "modes", None) is not None and len(traj.t):
        # a live run of this very system keeps the mode of every friction row (the signal holds one per
        # device): the row at or after the event at t
        i = int(np.clip(np.searchsorted(traj.t, t, side="right") - 1, 0, len(traj.t) - 1))
        run_modes = np.asarray(traj.modes[i], int).copy()
    if isinstance(modes, dict):
        names = [r.device.name for r in st.friction]
        _resolve_modes(c, modes)                   # names and mode codes checked there
        for name, mode in modes.items():
            for j, nm in enumerate(names):
                if nm == name:
                    run_modes[j] = _mode_code(name, mode)
    elif modes is not None:
        run_modes = _resolve_modes(c, modes)
    x, v = c.project(t, x, v, None, None, run_modes)
    return run_modes, (x, v)


def _start_point(c, t, modes):
    """None (``linearize`` takes the start values) or, when the scene's start speeds contradict the
    friction ``modes`` asked for, the consistent (x, v) nearest them: start positions kept, start speeds
    as guesses (``CompiledSystem.project``: a mass-weighted correction, i.e. the impulse that makes the
    stuck devices turn together and keeps the momentum), with a warning that says so."""
    import warnings
    import numpy as np
    from .compile.linear import _resolve_modes
    from .errors import StructureError

    arr = _resolve_modes(c, modes)
    try:
        c.initial_y(float(t), arr)
        return None
    except StructureError as exc:
        if "inconsistent start velocities" not in str(exc):
            raise
        reason = str(exc)
    st = c.structure
    guess_x = np.where(np.isfinite(st.start_pos), st.start_pos, 0.0)
    guess_v = np.where(np.isfinite(st.start_vel), st.start_vel, 0.0)
    x, v = c.project(float(t), guess_x, guess_v, st.start_pos, None, arr, starts=(0,))
    warnings.warn(f"linearize(modes=...): the start speeds of model '{c.model.name}' contradict the modes asked "
                  f"for ({reason.split('. Fix:')[0]}); linearised at the nearest speeds that obey them "
                  f"(mass-weighted, momentum kept). To linearise where a run is, pass at=res "
                  f"(m.linearize(at=m.simulate(T), t=T))", UserWarning, stacklevel=3)
    return x, v


def _state_space(c, t, modes, at, inputs, outputs):
    """``Model.linearize``'s first-order form: the operating point (a run's state at ``t``, the start values,
    a dict or ``(x, v)`` of the masses), made consistent with the block outputs, then ``state_space``."""
    import numpy as np
    from .compile.linear import _operating_point, _resolve_modes
    from .compile.statespace import state_space
    from .errors import ParameterError
    from .hybrid import attach
    from .result import Result

    attach(c)
    t = float(t)
    saved = c._t_right, c.__dict__.get("surface_sides")
    c._t_right, c.surface_sides = np.inf, None
    try:
        if isinstance(at, Result):
            modes, (x, v) = _run_point(c, at, t, modes)
            z = np.zeros(c.nz)
            for j, name in enumerate(c.state_names):
                if name not in at:
                    raise ParameterError(f"linearize(at=res): the result has no signal '{name}' (a state of model "
                                         f"'{c.model.name}'); pass a result of a run of this model")
                z[j] = at.at(name, t) - c.state_datum[j]
        else:
            modes = _resolve_modes(c, modes)
            x, v = _operating_point(c, t, modes, at)
            z = c.state_start.copy()
        y, yp = c.assemble_y(t, x, v, z, modes, rates=False)
        return state_space(c, y, yp, t, modes, inputs, outputs)
    finally:
        c._t_right, c.surface_sides = saved
