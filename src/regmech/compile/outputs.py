"""Named outputs of a trajectory, computed lazily from the stored (y, y').

Names (Modelica style): ``J1.phi``, ``J1.w``, ``J1.a``, ``J1.kinetic``;
``spring.phi_rel``, ``spring.w_rel``, ``spring.a_rel``, ``spring.tau``,
``spring.power`` (absorbed), ``spring.potential``; flange variables
``spring.flange_a.tau``, ``spring.flange_a.phi``, ``spring.flange_a.w``;
device states ``motor.i``; ``clutch.mode``. Translational components use
``s``, ``v``, ``f``, ``s_rel``, ``v_rel``.
"""

from __future__ import annotations

import numpy as np

from ..component import Body


class Trajectory:
    def __init__(self, compiled, t, Y, YP, left, modes):
        self.c = compiled
        self.t = np.asarray(t, float)
        self.Y = Y
        self.YP = YP
        self.left = np.asarray(left, bool)
        self.modes = modes
        self._mat: dict = {}
        self._index_cache = None

    def __getstate__(self):
        # the name index holds closures and the matrices are derived: both are rebuilt on first use
        state = self.__dict__.copy()
        state["_mat"] = {}
        state["_index_cache"] = None
        return state

    @property
    def _index(self):
        """name -> recipe, built on first use (it costs ~0.3 s for 1,000 masses)."""
        if self._index_cache is None:
            self._index_cache = self._build_index()
        return self._index_cache

    # matrices over time -------------------------------------------------------
    def _matrices(self):
        if self._mat:
            return self._mat
        c = self.c
        Y, YP = self.Y, self.YP
        X, V = Y[:, c.ix], Y[:, c.iv]
        A = YP[:, c.iv].copy()
        A[:, c.Dv] = Y[:, c.iad]
        LAM, Z = Y[:, c.ilam], Y[:, c.iz]
        E = X @ c.Sc.T.toarray() + c.e0c if c.Sc.shape[0] and c.n < 3000 else (c.Sc @ X.T).T + c.e0c
        DE = (c.Sc @ V.T).T
        DDE = (c.Sc @ A.T).T
        TAU = np.zeros_like(E)
        POT = np.zeros((len(self.t), len(c.groups)), dtype=object)
        pot_dev = {}
        for gi, g in enumerate(c.groups):
            out = g.evaluate_series(E, DE, Z, self.t, self.left)
            for r in range(g.tpl.k):
                TAU[:, g.row_index[:, r]] = out[r]
            pot = out[-1]
            for i, d in enumerate(g.devices):
                pot_dev[d.name] = pot[:, i]
        G = c.Gall
        GE = (G @ X.T).T + np.concatenate([c.e0p, np.zeros(c.mv), c.structure.offsets(c.structure.friction)]) if G.shape[0] else np.zeros((len(self.t), 0))
        GDE = (G @ V.T).T if G.shape[0] else GE
        GDDE = (G @ A.T).T if G.shape[0] else GE
        self._mat.update(X=X, V=V, A=A, LAM=LAM, Z=Z, E=E, DE=DE, DDE=DDE, TAU=TAU, GE=GE, GDE=GDE, GDDE=GDDE,
                         POT=pot_dev)
        return self._mat

    def _build_index(self):
        """name -> recipe (a callable of the matrices)."""
        c = self.c
        st = c.structure
        idx: dict = {}
        for k, node in enumerate(st.coord_node):
            for b in node.bodies:
                pn, wn, an, _ = b.var_names()
                idx[f"{b.name}.{pn}"] = lambda M, k=k: M["X"][:, k]
                idx[f"{b.name}.{wn}"] = lambda M, k=k: M["V"][:, k]
                idx[f"{b.name}.{an}"] = lambda M, k=k: M["A"][:, k]
                idx[f"{b.name}.kinetic"] = lambda M, k=k, m=b.mass: 0.5 * m * M["V"][:, k] ** 2
        for node in st.nodes:
            if node.grounded:
                for b in node.bodies:
                    pn, wn, an, _ = b.var_names()
                    for nm, val in ((pn, node.ground_position), (wn, 0.0), (an, 0.0)):
                        idx[f"{b.name}.{nm}"] = lambda M, val=val: np.full(len(self.t), val)
        comp_row = {id(r): ("c", i) for i, r in enumerate(st.compliant)}
        cons = st.position + st.speed + st.friction
        comp_row.update({id(r): ("g", i) for i, r in enumerate(cons)})
        node_of = {fl: nd for nd in st.nodes for fl in nd.flanges}
        for dev in st.devices:
            rows = st.rows[dev.name]
            where = [comp_row[id(r)] for r in rows]
            names = dev.rel_names.get(dev.domain, (None,) * 4)

            def rec(kind, i, what):
                if kind == "c":
                    key = {"e": "E", "de": "DE", "dde": "DDE", "tau": "TAU"}[what]
                else:
                    key = {"e": "GE", "de": "GDE", "dde": "GDDE", "tau": "LAM"}[what]
                return lambda M: M[key][:, i]

            k0, i0 = where[0]
            for nm, what in zip(names, ("e", "de", "dde", "tau")):
                if nm:
                    idx[f"{dev.name}.{nm}"] = rec(k0, i0, what)
            taus = [rec(k, i, "tau") for k, i in where]
            dess = [rec(k, i, "de") for k, i in where]
            idx[f"{dev.name}.power"] = lambda M, taus=taus, dess=dess: sum(tf(M) * df(M) for tf, df in zip(taus, dess))
            if dev.device_kind() == "compliant":
                idx[f"{dev.name}.potential"] = lambda M, n=dev.name: np.asarray(M["POT"][n], float)
            spec = dev.rows()
            fnames = {f for row in spec for f in row}
            for fname in fnames:
                coefs = [row.get(fname, 0.0) for row in spec]
                idx[f"{dev.name}.{fname}.{dev.get_flange(fname).domain == 'rotational' and 'tau' or 'f'}"] = (
                    lambda M, coefs=coefs, taus=taus: sum(cf * tf(M) for cf, tf in zip(coefs, taus) if cf))
                fl = dev.get_flange(fname)
                node = node_of[fl]
                kk = st.node_coord[node.index]
                pn, wn = ("phi", "w") if fl.domain == "rotational" else ("s", "v")
                if kk is None:
                    idx[f"{dev.name}.{fname}.{pn}"] = lambda M, p=node.ground_position: np.full(len(self.t), p)
                    idx[f"{dev.name}.{fname}.{wn}"] = lambda M: np.zeros(len(self.t))
                else:
                    idx[f"{dev.name}.{fname}.{pn}"] = lambda M, kk=kk: M["X"][:, kk]
                    idx[f"{dev.name}.{fname}.{wn}"] = lambda M, kk=kk: M["V"][:, kk]
        for j, name in enumerate(c.state_names):
            idx[name] = lambda M, j=j: M["Z"][:, j]
        if c.mf:
            for j, row in enumerate(st.friction):
                idx[f"{row.device.name}.mode"] = lambda M, j=j: self.modes[:, j].astype(float)
        return idx

    def names(self) -> list[str]:
        return sorted(self._index)

    def get(self, name: str) -> np.ndarray:
        recipe = self._index.get(name)
        if recipe is None:
            return None
        return np.asarray(recipe(self._matrices()), float)
