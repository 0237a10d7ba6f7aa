"""Named outputs of a trajectory, computed lazily from the stored (y, y').

Names (Modelica style): ``J1.phi``, ``J1.w``, ``J1.a``, ``J1.kinetic``;
``spring.phi_rel``, ``spring.w_rel``, ``spring.a_rel``, ``spring.tau``,
``spring.power`` (absorbed), ``spring.potential``; flange variables
``spring.flange_a.tau``, ``spring.flange_a.phi``, ``spring.flange_a.w``;
device states ``motor.i``; ``clutch.mode``. Translational components use
``s``, ``v``, ``f``, ``s_rel``, ``v_rel``.

Only what is asked for is computed, and only from the columns it needs: a
signal of one component costs O(points) memory and time, whatever the size of
the model. The recipes of a component (name -> function of the trajectory)
are made on the first request of one of its signals and kept; the device
kernel (``KernelGroup``) is evaluated for that one instance, not its whole
class. A model of 100,000 components read by a few of its signals thus never
holds the (points x components x signals) matrices nor a recipe per signal
of every component.

Stored: ``Y`` (points x N, every unknown) and ``YPv`` (points x n, the
derivatives of the speeds: the accelerations of the non-dummy coordinates);
the rest of ``y'`` is not needed by any output. A run may hand over ``YPv``
as a function computed on the first read of an acceleration (the ODE-form
path of a linear model: ``g(t, u)`` per output row is otherwise most of its
recording cost).
"""

from __future__ import annotations

import numpy as np

from ..modes import FREE, HELD, STUCK

#: which derived signals are time integrals of which (``Trajectory.integral_rate``), unless a device says otherwise
#: (``derived_integrals``)
DEFAULT_INTEGRALS = {"heat": "heat_flow"}


class Trajectory:
    """The output rows of a run and the compiled system that reads them.

    ``YP`` is either the full ``y'`` (points x ``c.N``) or only its speed
    columns ``y'[:, c.iv]`` (points x ``c.n``; ``solvers.common.Recorder``
    with ``yp_cols=c.iv`` records only those).
    """

    def __init__(self, compiled, t, Y, YP, left, modes):
        c = compiled
        self.c = c
        self.t = np.asarray(t, float)
        self.Y = Y
        # ``YP`` may be a function that returns it, called when an output first reads y' (the ODE-form path
        # computes the accelerations of its output rows only then: ``ode_driver._Sink.deferred_rates``)
        self._yp_fill = YP if callable(YP) else None
        self._YPv = None if callable(YP) else self._speed_columns(YP)
        self.left = np.asarray(left, bool)
        self.modes = modes
        self._recipes: dict = {}     # component name -> {signal name: recipe}
        self._maps = None            # name lookups over the whole structure, built on first use
        self._names = None

    def _speed_columns(self, YP):
        c = self.c
        YP = np.asarray(YP)
        if YP.ndim == 2 and YP.shape[1] == c.N and c.N != c.n:
            YP = YP[:, c.iv]         # a copy: the caller's full y' can be freed
        return YP

    @property
    def YPv(self):
        """The derivatives of the speeds (points x n), computed on first use when the run deferred them."""
        if self._YPv is None:
            fill, self._yp_fill = self._yp_fill, None
            self._YPv = self._speed_columns(fill())
        return self._YPv

    @YPv.setter
    def YPv(self, value):
        self._yp_fill, self._YPv = None, value

    def __getstate__(self):
        # recipes hold closures and the lookups are derived: both are rebuilt on first use; deferred
        # accelerations are computed first (the function that computes them is not pickled)
        self.YPv
        state = self.__dict__.copy()
        state["_recipes"] = {}
        state["_maps"] = None
        state["_names"] = None
        return state

    def __setstate__(self, state):
        if "YPv" in state:            # pickled before y' could be deferred
            state["_YPv"] = state.pop("YPv")
        elif "_YPv" not in state:     # a trajectory pickled when it kept all of y' and eager matrices
            c, YP = state["c"], state.pop("YP")
            state["_YPv"] = YP[:, c.iv] if YP.ndim == 2 and YP.shape[1] == c.N and c.N != c.n else YP
            for key in ("_mat", "_index_cache"):
                state.pop(key, None)
        state.update(_recipes={}, _maps=None, _names=None, _yp_fill=None)
        self.__dict__.update(state)

    # columns over time ----------------------------------------------------------
    def _x(self, k):
        return self.Y[:, self.c.ix[k]]

    def _v(self, k):
        return self.Y[:, self.c.iv[k]]

    def _a(self, k):
        c = self.c
        if c.is_dummy_v[k]:
            return self.Y[:, c.iad[c.pos_in_Dv[k]]]
        return self.YPv[:, k]

    @staticmethod
    def _combine(cols, coefs, column):
        """``sum_j coefs[j] * column(cols[j])`` accumulated in the row's order (as ``csr_matvec`` does)."""
        acc = None
        for k, cf in zip(cols, coefs):
            term = cf * column(int(k))
            acc = term if acc is None else acc + term
        return acc

    def _lookups(self):
        """Body -> coordinate (None: grounded) and node, device -> kernel instance, row -> its place. They
        depend on the compiled system only and are kept with it (read-only): on a chain of 10,000 inertias,
        building them for every result cost a tenth of a DOP853 run."""
        if self._maps is not None:
            return self._maps
        c = self.c
        kept = c.__dict__.get("_output_maps")
        if kept is not None:
            self._maps = kept
            return kept
        st = c.structure
        body_node = {}
        for node in st.nodes:
            for b in node.bodies:
                body_node.setdefault(b.name, node)
        node_of = {fl: nd for nd in st.nodes for fl in nd.flanges}
        place = {id(r): ("c", i) for i, r in enumerate(st.compliant)}
        place.update({id(r): ("g", i) for i, r in enumerate(st.position + st.speed + st.friction)})
        instance = {}
        for gi, g in enumerate(c.groups):
            for i, d in enumerate(g.devices):
                instance[d.name] = (g, i)
        states: dict = {}
        for j, name in enumerate(c.state_names):
            states.setdefault(name.rpartition(".")[0], []).append((name, j))
        modes: dict = {}
        if c.mf:
            for j, row in enumerate(st.friction):
                modes.setdefault(row.device.name, []).append(j)
        g_offsets = None
        if c.Gall.shape[0]:
            g_offsets = np.concatenate([c.e0p, np.zeros(c.mv), st.offsets(st.friction)])
        self._maps = c._output_maps = dict(body_node=body_node, node_of=node_of, place=place, instance=instance,
                                           states=states, modes=modes, g_offsets=g_offsets)
        return self._maps

    # rows of devices ---------------------------------------------------------------
    def _row_e(self, where, level):
        """Device coordinate of a row at ``level`` 0 (e), 1 (e') or 2 (e'')."""
        c = self.c
        kind, i = where
        col = (self._x, self._v, self._a)[level]
        M = c.Sc if kind == "c" else c.Gall
        lo, hi = M.indptr[i], M.indptr[i + 1]
        val = self._combine(M.indices[lo:hi], M.data[lo:hi], col)
        if val is None:
            val = np.zeros(len(self.t))
        if level == 0:
            val = val + (c.e0c[i] if kind == "c" else self._lookups()["g_offsets"][i])
        return val

    def _kernel(self, dev_name):
        """The kernel outputs (forces of the rows, state rates, Jacobian weights, potential) of one
        device over time, evaluated for that instance only."""
        g, i = self._lookups()["instance"][dev_name]
        c = self.c
        tpl = g.tpl
        n_t = len(self.t)
        col = lambda v: np.asarray(v, float).reshape(n_t, 1)
        rows = [("c", int(g.row_index[i, r])) for r in range(tpl.k)]
        args = [col(self._row_e(w, 0)) for w in rows] + [col(self._row_e(w, 1)) for w in rows] + \
               [col(self.Y[:, c.iz[int(g.state_index[i, s])]]) for s in range(len(tpl.states))] + \
               [col(self.Y[:, c.iz[int(g.read_index[i, j])]]) for j in range(len(tpl.reads))] + \
               [p[None, i:i + 1] for p in g.param_values] + \
               [np.array([sigs[i].value(t, lf) for t, lf in zip(self.t, self.left)], float).reshape(n_t, 1)
                for sigs in g.signals] + [self.t[:, None]]
        out = tpl.fn(*args)
        return [np.broadcast_to(np.asarray(o, dtype=float), (n_t, 1))[:, 0] for o in out]

    # recipes of one component ------------------------------------------------------------
    def _component_recipes(self, comp) -> dict:
        """name -> recipe (a function of nothing) for every signal of ``comp``."""
        from ..component import Body, Device
        c = self.c
        st = c.structure
        maps = self._lookups()
        n_t = len(self.t)
        idx: dict = {}
        if isinstance(comp, Body):
            node = maps["body_node"].get(comp.name)
            if node is not None:
                pn, wn, an, _ = comp.var_names()
                k = st.node_coord[node.index]
                if k is not None:
                    idx[f"{comp.name}.{pn}"] = lambda k=k: self._x(k)
                    idx[f"{comp.name}.{wn}"] = lambda k=k: self._v(k)
                    idx[f"{comp.name}.{an}"] = lambda k=k: self._a(k)
                    idx[f"{comp.name}.kinetic"] = lambda k=k, m=comp.mass: 0.5 * m * self._v(k) ** 2
                if node.grounded:
                    for nm, val in ((pn, node.ground_position), (wn, 0.0), (an, 0.0)):
                        idx[f"{comp.name}.{nm}"] = lambda val=val: np.full(n_t, val)
        if isinstance(comp, Device) and comp.name in st.rows:
            dev = comp
            rows = st.rows[dev.name]
            where = [maps["place"][id(r)] for r in rows]
            names = dev.rel_names.get(dev.domain, (None,) * 4)
            kernel = {}

            def kernel_out():
                if "out" not in kernel:
                    kernel["out"] = self._kernel(dev.name)
                return kernel["out"]

            def rec(w, what):
                kind, i = w
                if what == "tau":
                    if kind == "g":
                        j = i - c.mp - c.mv         # a friction row's mode column (its rows follow the rigid ones)
                        if 0 <= j < c.mf:
                            # a Free (or Held) row's law is lam = 0: exactly zero, not the round-off of the
                            # solve that carried it (1.8e-18 N m in a released shift clutch of six_speed_car,
                            # where a fresh machine's LU pivoted otherwise than the development one)
                            return lambda j=j, i=i: np.where(np.isin(self.modes[:, j], (FREE, HELD)), 0.0,
                                                             self.Y[:, c.ilam[i]])
                        return lambda: self.Y[:, c.ilam[i]]
                    inst = maps["instance"].get(dev.name)
                    if inst is None:         # a compliant row of a device of another kind: no kernel
                        return lambda: np.zeros(n_t)
                    r = [int(x) for x in inst[0].row_index[inst[1]]].index(i)
                    return lambda: kernel_out()[r]
                level = {"e": 0, "de": 1, "dde": 2}[what]
                if level and kind == "g" and 0 <= i - c.mp - c.mv < c.mf:
                    # a Stuck row's law is w_rel = 0 (and so a_rel = 0): exactly zero, not the solvers' residue of
                    # it, which made the device's power and heat_flow (lam w_rel) noise of either sign there (a loss
                    # element supplying power: 1e-12 W on CoupledClutches, 4e-5 W on six_speed_car's stuck shift
                    # clutch with IDA at rtol 1e-6) and a_rel up to 0.1 rad/s^2 there; its own states' rates read
                    # it so (``friction_rows._pinned``). The flanges' speeds keep the residue (2e-7 rad/s there)
                    return lambda j=i - c.mp - c.mv: np.where(self.modes[:, j] == STUCK, 0.0,
                                                              self._row_e(w, level))
                return lambda: self._row_e(w, level)

            for nm, what in zip(names, ("e", "de", "dde", "tau")):
                if nm:
                    idx[f"{dev.name}.{nm}"] = rec(where[0], what)
            taus = [rec(w, "tau") for w in where]
            dess = [rec(w, "de") for w in where]
            idx[f"{dev.name}.power"] = lambda: sum(tf() * df() for tf, df in zip(taus, dess))
            if dev.device_kind() == "compliant":
                idx[f"{dev.name}.potential"] = lambda: np.asarray(kernel_out()[-1], float)
            spec = dev.rows()
            fnames = {f for row in spec for f in row}
            for fname in fnames:
                coefs = [row.get(fname, 0.0) for row in spec]
                fl = dev.get_flange(fname)
                idx[f"{dev.name}.{fname}.{fl.domain == 'rotational' and 'tau' or 'f'}"] = (
                    lambda coefs=coefs: sum(cf * tf() for cf, tf in zip(coefs, taus) if cf))
                node = maps["node_of"][fl]
                kk = st.node_coord[node.index]
                pn, wn = ("phi", "w") if fl.domain == "rotational" else ("s", "v")
                if kk is None:
                    idx[f"{dev.name}.{fname}.{pn}"] = lambda p=node.ground_position: np.full(n_t, p)
                    idx[f"{dev.name}.{fname}.{wn}"] = lambda: np.zeros(n_t)
                else:
                    idx[f"{dev.name}.{fname}.{pn}"] = lambda kk=kk: self._x(kk)
                    idx[f"{dev.name}.{fname}.{wn}"] = lambda kk=kk: self._v(kk)
            for name, j in maps["states"].get(dev.name, ()):
                idx[name] = lambda j=j: self.Y[:, c.iz[j]] + c.state_datum[j]
            if dev.derived_units:
                self._derived_recipes(dev, idx, where, taus, dess, maps)
            for j in maps["modes"].get(dev.name, ()):
                idx[f"{dev.name}.mode"] = lambda j=j: self.modes[:, j].astype(float)
        return idx

    def _derived_recipes(self, dev, idx, where, taus, dess, maps) -> None:
        """Recipes of the device's ``derived_units`` (``Device.derived``): all computed together on the
        first request, from the rows, forces and states of this one instance (``taus``, ``dess``: the recipes of
        its rows' forces and relative speeds, with what a friction row's mode pins at zero)."""
        from ..errors import ModelError, RegmechError
        from .reads import recorded_reads
        cache: dict = {}

        def compute():
            if "out" not in cache:
                e = [self._row_e(w, 0) for w in where]
                de = [np.asarray(df(), float) for df in dess]
                tau = [np.asarray(tf(), float) for tf in taus]
                z = {name.rpartition(".")[2]: self.Y[:, self.c.iz[j]] + self.c.state_datum[j]
                     for name, j in maps["states"].get(dev.name, ())}
                who = f"{type(dev).__name__} '{dev.name}'"
                try:
                    with recorded_reads(self.c, dev, self.t, self.left, self.Y):
                        out = dev.derived(self.t, self.left, e, de, tau, z)
                except RegmechError:
                    raise
                except Exception as exc:      # a user's derived(): said as a regmech error naming the device
                    raise ModelError(f"{who}: derived() failed ({type(exc).__name__}: {exc}); it computes the "
                                     f"signals {sorted(dev.derived_units)} from the run with numpy") from exc
                missing = set(dev.derived_units) - set(out if isinstance(out, dict) else {})
                if missing:
                    raise ModelError(f"{who}: derived() returned no {sorted(missing)}, which derived_units "
                                     f"declares; return a dict with every declared signal")
                done = {}
                for k in dev.derived_units:
                    try:
                        val = np.broadcast_to(np.asarray(out[k], float), self.t.shape)
                    except (TypeError, ValueError) as exc:
                        raise ModelError(f"{who}: derived signal '{k}' is not a number per output instant "
                                         f"({exc}); return an array of shape {self.t.shape}") from exc
                    bad = ~np.isfinite(val)
                    if bad.any():
                        raise ModelError(f"{who}: derived signal '{k}' is not finite at t={self.t[bad][0]:.6g}; "
                                         f"check the device's parameters and derived()")
                    done[k] = val
                cache["out"] = done
            return cache["out"]

        for key in dev.derived_units:
            idx[f"{dev.name}.{key}"] = lambda key=key: compute()[key]

    def _recipes_of(self, comp_name):
        hit = self._recipes.get(comp_name)
        if hit is None:
            comp = self.c.model.components.get(comp_name)
            hit = self._component_recipes(comp) if comp is not None else {}
            self._recipes[comp_name] = hit
        return hit

    def _recipe(self, name: str):
        """The recipe of ``name``: its component is the longest prefix before a '.' that names one
        (parts of a subsystem are named ``sub.part``)."""
        if not isinstance(name, str):
            return None
        comps = self.c.model.components
        cut = len(name)
        while True:
            cut = name.rfind(".", 0, cut)
            if cut <= 0:
                return None
            if name[:cut] in comps:
                recipe = self._recipes_of(name[:cut]).get(name)
                if recipe is not None:
                    return recipe

    # public -----------------------------------------------------------------------------
    def has(self, name: str) -> bool:
        return self._recipe(name) is not None

    def names(self) -> list[str]:
        """Every signal name, sorted (made once; the recipes themselves are not kept)."""
        if self._names is None:
            out = []
            for comp in self.c.model.components.values():
                out.extend(self._component_recipes(comp))
            self._names = sorted(set(out))
        return list(self._names)

    def integral_rate(self, name: str) -> str | None:
        """The signal whose time integral ``name`` is, or None: a device's ``heat`` [J] is the integral of its
        ``heat_flow`` [W], a thermal mass's ``heat_to_ambient`` [J] that of its ``heat_flow_to_ambient`` [W]
        (a device's ``derived_integrals``, by default ``{"heat": "heat_flow"}``), which ``Result`` computes from
        the model's laws between the rows (``solvers.quadrature``) rather than by the trapezoid of
        ``Device.derived``."""
        owner, _, key = name.rpartition(".") if isinstance(name, str) else ("", "", "")
        comp = self.c.model.components.get(owner)
        units = getattr(comp, "derived_units", None) or {}
        rate = (getattr(comp, "derived_integrals", None) or DEFAULT_INTEGRALS).get(key)
        if rate is not None and key in units and rate in units:
            return f"{owner}.{rate}"
        return None

    def get(self, name: str) -> np.ndarray | None:
        recipe = self._recipe(name)
        if recipe is None:
            return None
        return np.array(recipe(), float)
