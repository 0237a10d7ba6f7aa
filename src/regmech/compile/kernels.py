"""Class kernels: a device class's symbolic laws, differentiated and
lambdified once, evaluated for all instances of the class in one numpy call.

For a class with ``k`` rows and internal states ``z`` the template holds

* ``tau = laws(e, de)`` (k expressions), ``dz = derivatives(e, de)``,
* their nonzero partial derivatives w.r.t. ``e``, ``de`` and ``z``
  (the class's Jacobian *pattern* is known symbolically, so identically
  zero entries cost nothing),
* ``potential(e)`` for the energy audit.

Templates are cached per (class, kind): a model with 10,000 springs
differentiates ``c*phi_rel`` once.
"""

from __future__ import annotations

import types
from dataclasses import dataclass

import numpy as np
import sympy

from ..component import Device, numeric_params, signal_params
from ..errors import ModelError

_TEMPLATES: dict = {}


class _SymbolicSelf:
    """Stands in for ``self`` while a class's laws are evaluated symbolically."""

    def __init__(self, cls, symbols: dict):
        object.__setattr__(self, "_cls", cls)
        object.__setattr__(self, "_symbols", symbols)

    def __getattr__(self, name):
        syms = object.__getattribute__(self, "_symbols")
        if name in syms:
            return syms[name]
        attr = getattr(object.__getattribute__(self, "_cls"), name)
        if isinstance(attr, types.FunctionType):
            return types.MethodType(attr, self)
        return attr


@dataclass
class Template:
    cls: type
    k: int                      # rows
    states: list[str]
    params: list[str]           # numeric parameters used
    inputs: list[str]           # signal parameters used
    fn: object                  # (e..., de..., z..., params..., inputs..., t) -> [tau..., dz..., jac entries..., potential]
    jac_entries: list[tuple]    # (output, wrt) with output in ('tau', i) / ('dz', i), wrt in ('e', j) / ('de', j) / ('z', j)
    n_out: int


def _lambdify(args, exprs):
    return sympy.lambdify(args, exprs, modules="numpy", cse=True)


def template_for(dev: Device) -> Template:
    cls = type(dev)
    key = (cls, dev.device_kind(), len(dev.rows()))
    tpl = _TEMPLATES.get(key)
    if tpl is not None:
        return tpl
    k = key[2]
    states = list(cls.states)
    e = sympy.symbols(f"_e0:{k}", real=True)
    de = sympy.symbols(f"_de0:{k}", real=True)
    z = [sympy.Symbol(f"_z_{s}", real=True) for s in states]
    t = sympy.Symbol("_t", real=True)
    pnames = numeric_params(cls)
    inames = signal_params(cls)
    syms = {p: sympy.Symbol(p, real=True) for p in pnames + inames}
    syms.update({s: zs for s, zs in zip(states, z)})
    syms["time"] = t
    proxy = _SymbolicSelf(cls, syms)
    try:
        taus = [sympy.sympify(x) for x in cls.laws(proxy, list(e), list(de))]
        dz = [sympy.sympify(x) for x in cls.derivatives(proxy, list(e), list(de))]
        pot = sympy.sympify(cls.potential(proxy, list(e)))
    except (TypeError, AttributeError, sympy.SympifyError) as exc:
        raise ModelError(
            f"{cls.__name__}: its law could not be written symbolically ({exc}); laws must use arithmetic and "
            f"sympy functions (sympy.sin, sympy.Piecewise, ...) of the arguments and self.<parameter>") from exc
    if len(taus) != k:
        raise ModelError(f"{cls.__name__}: laws() returned {len(taus)} forces for {k} rows")
    if len(dz) != len(states):
        raise ModelError(f"{cls.__name__}: derivatives() returned {len(dz)} expressions for states {states}")
    jac_entries, jac_exprs = [], []
    wrt = [("e", j, s) for j, s in enumerate(e)] + [("de", j, s) for j, s in enumerate(de)] + \
          [("z", j, s) for j, s in enumerate(z)]
    outs = [("tau", i, x) for i, x in enumerate(taus)] + [("dz", i, x) for i, x in enumerate(dz)]
    for oname, oi, ox in outs:
        for wname, wj, ws in wrt:
            d = sympy.diff(ox, ws)
            if d != 0:
                jac_entries.append(((oname, oi), (wname, wj)))
                jac_exprs.append(d)
    used = set().union(*(x.free_symbols for x in taus + dz + jac_exprs + [pot])) if (taus or dz) else set()
    params = [p for p in pnames if syms[p] in used]
    inputs = [p for p in inames if syms[p] in used]
    args = list(e) + list(de) + z + [syms[p] for p in params] + [syms[p] for p in inputs] + [t]
    fn = _lambdify(args, taus + dz + jac_exprs + [pot])
    tpl = Template(cls, k, states, params, inputs, fn, jac_entries, len(taus) + len(dz) + len(jac_exprs) + 1)
    _TEMPLATES[key] = tpl
    return tpl


class KernelGroup:
    """All instances of one template; evaluates them together.

    ``row_index[i, r]``: global compliant row of instance i, row r;
    ``state_index[i, s]``: global internal-state index.
    """

    def __init__(self, tpl: Template, devices: list[Device], row_index: np.ndarray, state_index: np.ndarray):
        self.tpl = tpl
        self.devices = devices
        self.row_index = row_index
        self.state_index = state_index
        self.n = len(devices)
        pvals = []
        for p in tpl.params:
            vals = np.array([np.nan if d._values[p] is None else float(d._values[p]) for d in devices])
            pvals.append(vals)
        self.param_values = pvals
        self.signals = [[d._values[p] for d in devices] for p in tpl.inputs]

    def inputs_at(self, t: float, left: bool = False) -> list[np.ndarray]:
        return [np.fromiter((s.value(t, left) for s in sigs), float, self.n) for sigs in self.signals]

    def evaluate(self, e: np.ndarray, de: np.ndarray, z: np.ndarray, t: float, left: bool = False):
        """e, de: global compliant-row vectors; z: global state vector. Returns list of arrays."""
        tpl = self.tpl
        args = [e[self.row_index[:, r]] for r in range(tpl.k)] + \
               [de[self.row_index[:, r]] for r in range(tpl.k)] + \
               [z[self.state_index[:, s]] for s in range(len(tpl.states))] + \
               self.param_values + self.inputs_at(t, left) + [t]
        out = tpl.fn(*args)
        return [np.broadcast_to(np.asarray(o, dtype=float), (self.n,)) for o in out]

    def evaluate_series(self, E: np.ndarray, DE: np.ndarray, Z: np.ndarray, T: np.ndarray, left: np.ndarray):
        """Vectorised over time: E (T x rows), returns list of (T x n) arrays."""
        tpl = self.tpl
        args = [E[:, self.row_index[:, r]] for r in range(tpl.k)] + \
               [DE[:, self.row_index[:, r]] for r in range(tpl.k)] + \
               [Z[:, self.state_index[:, s]] for s in range(len(tpl.states))] + \
               [p[None, :] for p in self.param_values] + \
               [np.array([[s.value(t, lf) for s in sigs] for t, lf in zip(T, left)]).reshape(len(T), self.n)
                for sigs in self.signals] + [T[:, None]]
        out = tpl.fn(*args)
        return [np.broadcast_to(np.asarray(o, dtype=float), (len(T), self.n)) for o in out]
