"""Inputs of friction laws taken from the state: what a friction device reads besides ``|w_rel|`` and t.

A device lists them (``FrictionDevice.law_inputs``): ``("state", name)`` one of its own states (a
thermal mass's temperature ``T``, placed in the state vector ``z`` by ``CompiledSystem``), or
``("command", device, key)`` a value another device computes from its own rows and states (a
controller's output driving a clutch's normal force, ``Controller.command``). Here each becomes an
evaluator of the unknowns ``y``: its value and its gradient over the few columns of ``y`` it reads
(fixed, so the Jacobian pattern knows them), evaluated at every residual, Jacobian, event function
and mode-logic call. The friction rows pass the values to the device's laws as ``q``.

A command is written symbolically once (``command_law`` of the device's class, with the same proxy
as its laws), differentiated and lambdified; it reads the device's rows ``e = S x + e0``, ``de = S
v``, its states, its parameters and signals, and time.
"""

from __future__ import annotations

import numpy as np
import sympy

from ..component import numeric_params, signal_params
from ..errors import ModelError
from .kernels import _lambdify, _SymbolicSelf
from .reads import state_column


class StateInput:
    """``q = y[col] + datum``: a state of the friction device itself (``datum``: what its entry of ``y``
    departs from, ``CompiledSystem.state_datum``)."""

    def __init__(self, col: int, datum: float = 0.0):
        self.col = int(col)
        self.datum = float(datum)
        self.cols = np.array([self.col], np.int64)
        self._one = np.ones(1)

    def value(self, t, y, left):
        return float(y[self.col]) + self.datum

    def value_and_gradient(self, t, y, left):
        return float(y[self.col]) + self.datum, self._one


class CommandInput:
    """``q = command(e, de, z, params, signals, t)`` of a compliant device (a controller)."""

    def __init__(self, c, dev, key: str, reader):
        group = next(((g, i) for g in c.groups for i, d in enumerate(g.devices) if d is dev), None)
        if group is None:
            raise ModelError(f"{reader}: its normal force is {type(dev).__name__} '{dev.name}'.command({key!r}), but "
                             f"that device is not part of this model (or has no rows); add it with model.add(...) and "
                             f"connect its sensors")
        g, i = group
        if not hasattr(type(dev), "command_law"):
            raise ModelError(f"{reader}: {type(dev).__name__} '{dev.name}' gives no commands (command_law)")
        rows = [int(r) for r in g.row_index[i]]
        sidx = [int(s) for s in g.state_index[i]]
        k = len(rows)
        self.dev, self.key, self.k = dev, key, k
        self.fn, self.params, self.signals = _command_function(dev, key, k)
        self.param_values = [float(dev._values[p]) for p in self.params]
        self.sigs = [dev._values[p] for p in self.signals]
        # the rows' coefficients: e_r = S[r] x + e0[r], de_r = S[r] v
        S = c.Sc[rows].toarray() if k else np.zeros((0, c.n))
        used_cols = np.nonzero(np.any(S != 0, axis=0))[0]
        self.S = S[:, used_cols]
        self.e0 = c.e0c[rows] if k else np.zeros(0)
        self.ix = c.ix[used_cols]
        self.iv = c.iv[used_cols]
        self.iz = c.iz[sidx] if sidx else np.zeros(0, np.int64)
        self.cols = np.concatenate([self.ix, self.iv, self.iz]).astype(np.int64)
        self._nx = len(used_cols)

    # pickling: the lambdified function is made again from the device on first use
    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("fn", None)
        return state

    def __getattr__(self, name):
        if name != "fn" or "dev" not in self.__dict__:
            raise AttributeError(name)
        self.fn = _command_function(self.dev, self.key, self.k)[0]
        return self.fn

    def _call(self, t, y, left):
        e = self.S @ y[self.ix] + self.e0
        de = self.S @ y[self.iv]
        z = y[self.iz]
        out = self.fn(*e, *de, *z, *self.param_values, *(s.value(t, left) for s in self.sigs), t)
        return [float(o) for o in out]

    def value(self, t, y, left):
        return self._call(t, y, left)[0]

    def value_and_gradient(self, t, y, left):
        out = self._call(t, y, left)
        k = self.k
        d_e, d_de, d_z = np.array(out[1:1 + k]), np.array(out[1 + k:1 + 2 * k]), np.array(out[1 + 2 * k:])
        grad = np.concatenate([d_e @ self.S, d_de @ self.S, d_z]) if k else d_z
        return out[0], grad


def _command_function(dev, key: str, k: int):
    """``(fn, params, signals)``: command ``key`` of ``dev`` (``k`` rows) and its gradient over ``(e, de, z)``,
    lambdified as ``fn(e..., de..., z..., params..., signals..., t) -> [value, gradient...]``."""
    cls = type(dev)
    e = sympy.symbols(f"_e0:{k}", real=True)
    de = sympy.symbols(f"_de0:{k}", real=True)
    z = [sympy.Symbol(f"_z_{s}", real=True) for s in cls.states]
    t = sympy.Symbol("_t", real=True)
    pnames, inames = numeric_params(cls), signal_params(cls)
    syms = {p: sympy.Symbol(p, real=True) for p in pnames + inames}
    syms.update(dict(zip(cls.states, z)))
    syms["time"] = t
    try:
        expr = sympy.sympify(cls.command_law(_SymbolicSelf(cls, syms), list(e), list(de), key))
    except (TypeError, AttributeError, sympy.SympifyError) as exc:
        raise ModelError(f"{cls.__name__}: its command {key!r} could not be written symbolically ({exc}); use "
                         f"arithmetic and sympy functions of the measurements, states and parameters") from exc
    grads = [sympy.diff(expr, s) for s in list(e) + list(de) + z]
    used = expr.free_symbols.union(*(gx.free_symbols for gx in grads))
    params = [p for p in pnames if syms[p] in used]
    signals = [p for p in inames if syms[p] in used]
    fn = _lambdify(list(e) + list(de) + z + [syms[p] for p in params + signals] + [t], [expr] + grads)
    return fn, params, signals


def build_inputs(c, devices, own_states) -> list:
    """Per friction device the list of its input evaluators (``[]`` without inputs). ``own_states[j]``: name ->
    index in ``z`` of device j's own states."""
    out = []
    for j, dev in enumerate(devices):
        specs = dev.law_inputs() if hasattr(dev, "law_inputs") else []
        ins = []
        for spec in specs:
            if spec[0] == "state":
                k = own_states[j][spec[1]]
                ins.append(StateInput(c.iz[k], c.state_datum[k]))
            elif spec[0] == "command" and not hasattr(type(spec[1]), "command_law") \
                    and state_column(c, spec[1], spec[2]) is not None:
                # a block's output (``component.StateRead``): an unknown of the DAE itself
                k = state_column(c, spec[1], spec[2])
                ins.append(StateInput(c.iz[k], c.state_datum[k]))
            elif spec[0] == "command":
                ins.append(CommandInput(c, spec[1], spec[2], f"{type(dev).__name__} '{dev.name}'"))
            else:
                raise ModelError(f"{type(dev).__name__} '{dev.name}': unknown law input {spec!r}")
        out.append(ins)
    return out
