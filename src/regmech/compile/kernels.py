"""Class kernels: a device class's symbolic laws, differentiated and
lambdified once, evaluated for all instances of the class in one numpy call.

For a class with ``k`` rows and internal states ``z`` the template holds

* ``tau = laws(e, de)`` (k expressions), ``dz = derivatives(e, de)``,
* their nonzero partial derivatives w.r.t. ``e``, ``de`` and ``z``
  (the class's Jacobian *pattern* is known symbolically, so identically
  zero entries cost nothing),
* ``potential(e)`` for the energy audit,
* whether the class is *affine*: every partial derivative depends on the
  parameters only, so ``tau = tau(0) + J_e e + J_de de + J_z z`` with
  constant ``J``. The compiler folds such devices (springs, dampers, torque
  sources) into constant sparse matrices; only the offset ``tau(0)`` is
  evaluated at run time, and only when it depends on time or inputs.

Templates are cached per (class, kind, rows): a model with 10,000 springs
differentiates ``c*phi_rel`` once.
"""

from __future__ import annotations

import math
import types
from dataclasses import dataclass

import numpy as np
import sympy
from sympy.printing.numpy import SciPyPrinter
from sympy.printing.precedence import PRECEDENCE

from ..component import Device, numeric_params, signal_params
from ..errors import ModelError
from ..signals import Constant, Sine, Step

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
    """One device class (and kind and row count), compiled.

    All functions take ``(e..., de..., z..., params..., inputs..., t)``:

    * ``fn`` -> ``[tau..., dz..., jac entries..., potential]`` (everything);
    * ``res_fn`` -> ``[tau..., dz...]`` (the residual needs only these);
    * ``jac_fn`` -> ``[jac entries...]``;
    * ``offset_fn(params..., inputs..., t)`` -> ``[tau(0)..., dz(0)...]`` at
      ``e = de = z = 0`` (used for affine classes only).
    """

    cls: type
    k: int                      # rows
    states: list[str]
    params: list[str]           # numeric parameters used
    inputs: list[str]           # signal parameters used
    fn: object
    jac_entries: list[tuple]    # (output, wrt) with output in ('tau', i) / ('dz', i), wrt in ('e', j) / ('de', j) / ('z', j) / ('r', j)
    n_out: int
    res_fn: object = None
    jac_fn: object = None
    affine: bool = False        # all jac entries depend on parameters only
    offset_fn: object = None
    offset_varies: bool = False  # tau(0)/dz(0) depend on time or inputs
    offset_uses_time: bool = False  # ... on time itself (not only through inputs)
    #: ``offset_coef_fn(params...)`` -> ``[[d offset_o / d input_j]...]`` when the varying offsets are linear in
    #: the inputs with coefficients of the parameters alone and do not use time (a Torque's ``tau(0) = tau``):
    #: the residual then multiplies the signal values themselves (``EvaluationPlan``'s input slots)
    offset_coef_fn: object = None
    #: ``surf_fn(args...)`` -> ``[g...]``, the class's switching surfaces (``Device.switching_surfaces``), and
    #: the state code each one stands for; None / () for a smooth law
    surf_fn: object = None
    surf_codes: tuple = ()
    #: the argument symbols and the expressions of ``res_fn``, ``jac_fn`` and ``surf_fn`` (``scalar``)
    exprs: dict = None
    #: their Python-float versions, built on first use (``scalar``); None: not printable that way
    scalar_fns: dict = None
    #: signal parameters read from the unknowns (``component.StateRead``): arguments ``r`` after ``z``
    reads: tuple = ()

    def scalar(self, fn):
        """The Python-float version of ``res_fn``, ``jac_fn`` or ``surf_fn`` (``math`` functions and ``if``/``else``
        for ``Piecewise``), or None. A class with one instance in the model calls it instead of the numpy
        kernel: on one-element arrays each numpy operation costs about a microsecond of dispatch, and
        ElastoBacklash's residual (30 operations) took 34 us a call (fuzz CI seed 1005: 318,076 calls, 20 % of
        its time); the float version takes a few. Built once per class and process."""
        if self.exprs is None:
            return None
        name = "res" if fn is self.res_fn else "jac" if fn is self.jac_fn else "surf" if fn is self.surf_fn else None
        if name is None or name not in self.exprs:
            return None
        if self.scalar_fns is None:
            self.scalar_fns = {}
        if name not in self.scalar_fns:
            args, exprs = self.exprs[name]
            try:
                # ``math`` by name too: the printer writes ``math.copysign`` for sign and ``math.floor`` for floor
                self.scalar_fns[name] = sympy.lambdify(args, exprs, modules=[{"math": math}, "math"], cse=True)
            except Exception:       # noqa: BLE001 - a function math has no version of: the numpy kernel serves
                self.scalar_fns[name] = None
        return self.scalar_fns[name]


class _KernelPrinter(SciPyPrinter):
    """numpy code (scipy.special for the special functions: erf, gamma, Bessel) with small integer powers of symbols written as products.

    ``x**3`` on a float array goes through the general ``pow`` (about 50 ns
    per element with numpy 2); ``x*x*x`` costs about 1 ns. After common
    subexpression elimination most bases are symbols; other bases keep
    ``**`` so that they are not evaluated several times.
    """

    def _print_Pow(self, expr, rational=False):
        base, exp = expr.base, expr.exp
        if base.is_Atom and exp.is_Integer and 2 <= abs(int(exp)) <= 8:
            b = self.parenthesize(base, PRECEDENCE["Mul"], strict=False)
            product = "*".join([b] * abs(int(exp)))
            return f"({product})" if exp > 0 else f"(1/({product}))"
        return super()._print_Pow(expr, rational=rational)


    def _print_Piecewise(self, expr):
        """Nested ``numpy.where`` instead of NumPyPrinter's ``numpy.select``: the same first-true-branch rule, but
        ``select`` broadcasts its lists on every call, 50 us on the one-element arrays of a class with one
        instance; it was 46 % of a run of fuzz seed 60016 (a lossy gear, an end stop, a sign load: 156,897
        selects in 31,318 residual calls). ``where`` costs about 2 us there."""
        where = self._module_format("numpy.where")
        pieces = list(expr.args)
        if pieces and pieces[-1].cond == sympy.true:
            out = self._print(pieces.pop().expr)
        else:
            out = self._module_format("numpy.nan")
        for piece in reversed(pieces):
            out = f"{where}({self._print(piece.cond)}, {self._print(piece.expr)}, {out})"
        return out


def _lambdify(args, exprs, where: str = ""):
    """numpy code of ``exprs`` in ``args``; a function it cannot print (``sympy.besselj``, ``LambertW``) is a
    ``ModelError`` naming the device ``where``."""
    try:
        return sympy.lambdify(args, exprs, modules=["scipy", "numpy"], printer=_KernelPrinter, cse=True)
    except Exception as exc:        # noqa: BLE001 - sympy's printers raise several kinds; each is named
        raise ModelError(
            f"{where or 'a device'}: its law uses a function regmech cannot evaluate ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0]}); write it with arithmetic, sympy.sqrt/exp/log/sin/cos/tanh/atan/Abs/"
            f"Min/Max/sign/Heaviside/floor and sympy.Piecewise") from exc


#: functions constant between their jumps: a law using them jumps there, and its derivative is zero elsewhere
_STEPWISE = (sympy.Piecewise, sympy.sign, sympy.Heaviside, sympy.floor, sympy.ceiling, sympy.frac)


def _derivative(where: str, x, wrt):
    """``d x / d wrt`` almost everywhere: the Dirac deltas of jumps (``sign``, ``Heaviside``) and the
    derivatives of stepwise functions (``floor``) are zero between the jumps, where the solvers use it; any
    other derivative sympy cannot form (a user's undefined function) is a ``ModelError`` naming the device."""
    d = sympy.diff(x, wrt)
    if not d.has(sympy.DiracDelta, sympy.Derivative):
        return d
    d = d.replace(sympy.DiracDelta, lambda *args: sympy.S.Zero)
    d = d.replace(lambda a: isinstance(a, sympy.Derivative) and isinstance(a.expr, _STEPWISE), lambda a: sympy.S.Zero)
    if d.has(sympy.Derivative):
        raise ModelError(f"{where}: the derivative of its law with respect to its argument {wrt} cannot be formed "
                         f"({d}); write the law with functions sympy differentiates (arithmetic, sqrt, exp, sin, "
                         f"Piecewise, ...)")
    return d


def _law_expr(where: str, what: str, x, known: set):
    """``x``, what a device's law returned, as a sympy expression of its arguments, parameters, states and time
    (``known``); a string, or anything naming other symbols, is a ``ModelError`` naming the device (a string
    ``"x"`` became the symbol x, and the compiled law failed at its first call with a NameError)."""
    if isinstance(x, str):
        raise ModelError(f"{where}: {what} returned the string {x!r}; a law returns an expression of its "
                         f"arguments and self.<parameter> (e.g. self.c * rel), not text")
    try:
        expr = sympy.sympify(x)
    except (sympy.SympifyError, TypeError, ValueError) as exc:
        raise ModelError(f"{where}: {what} returned {x!r}, which is not an expression ({exc}); a law returns an "
                         f"expression of its arguments and self.<parameter>") from exc
    stray = sorted(str(sym) for sym in getattr(expr, "free_symbols", ()) if sym not in known)
    if stray:
        raise ModelError(f"{where}: {what} returned {expr}, which uses the unknown symbol(s) {stray}; a law may use "
                         f"only its arguments, self.<parameter>, its states and self.time")
    return expr


def read_params(dev: Device) -> tuple:
    """The signal parameters of ``dev`` whose value is read from the unknowns (``component.StateRead``)."""
    from ..component import StateRead
    return tuple(p for p in signal_params(type(dev)) if isinstance(dev._values.get(p), StateRead))


def template_for(dev: Device) -> Template:
    cls = type(dev)
    reads = read_params(dev)
    key = (cls, dev.device_kind(), len(dev.rows())) + ((reads,) if reads else ())
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
    inames = [p for p in signal_params(cls) if p not in reads]
    syms = {p: sympy.Symbol(p, real=True) for p in pnames + inames + list(reads)}
    r = [syms[p] for p in reads]
    syms.update({s: zs for s, zs in zip(states, z)})
    syms["time"] = t
    proxy = _SymbolicSelf(cls, syms)
    where = f"{cls.__name__} '{dev.name}'"
    known = set(e) | set(de) | set(z) | {t} | set(syms.values())
    try:
        taus = [_law_expr(where, "laws()", x, known) for x in cls.laws(proxy, list(e), list(de))]
        dz = [_law_expr(where, "derivatives()", x, known) for x in cls.derivatives(proxy, list(e), list(de))]
        pot = _law_expr(where, "potential()", cls.potential(proxy, list(e)), known)
        surfaces = list(cls.switching_surfaces(proxy, list(e), list(de)))
        surf = [_law_expr(where, "switching_surfaces()", g, known) for g, _ in surfaces]
        surf_codes = tuple(int(code) for _, code in surfaces)
    except ModelError:
        raise
    except Exception as exc:
        # the user's own law raised (a ZeroDivisionError, a KeyError, a numpy function given a symbol): named
        raise ModelError(
            f"{where}: its law could not be written symbolically ({type(exc).__name__}: {exc}); laws must use "
            f"arithmetic and sympy functions (sympy.sin, sympy.Piecewise, ...) of the arguments and "
            f"self.<parameter>") from exc
    if len(taus) != k:
        raise ModelError(f"{cls.__name__}: laws() returned {len(taus)} forces for {k} rows")
    if len(dz) != len(states):
        raise ModelError(f"{cls.__name__}: derivatives() returned {len(dz)} expressions for states {states}")
    jac_entries, jac_exprs = [], []
    wrt = [("e", j, s) for j, s in enumerate(e)] + [("de", j, s) for j, s in enumerate(de)] + \
          [("z", j, s) for j, s in enumerate(z)] + [("r", j, s) for j, s in enumerate(r)]
    outs = [("tau", i, x) for i, x in enumerate(taus)] + [("dz", i, x) for i, x in enumerate(dz)]
    for oname, oi, ox in outs:
        for wname, wj, ws in wrt:
            d = _derivative(where, ox, ws)
            if d != 0:
                jac_entries.append(((oname, oi), (wname, wj)))
                jac_exprs.append(d)
    if any(code == 0 for code in surf_codes):
        raise ModelError(f"{cls.__name__}: switching_surfaces() gave a state code 0; 0 is the open state, "
                         f"give each surface a nonzero code")
    used = set().union(*(x.free_symbols for x in taus + dz + jac_exprs + [pot] + surf)) if (taus or dz) else set()
    params = [p for p in pnames if syms[p] in used]
    inputs = [p for p in inames if syms[p] in used]
    param_syms = [syms[p] for p in params]
    input_syms = [syms[p] for p in inputs]
    args = list(e) + list(de) + z + r + param_syms + input_syms + [t]
    fn = _lambdify(args, taus + dz + jac_exprs + [pot], where)
    # affine: the Jacobian is a function of the parameters alone (no e, de, z, t or inputs)
    variable = set(e) | set(de) | set(z) | set(r) | {t} | set(input_syms)
    affine = not any(x.free_symbols & variable for x in jac_exprs)
    if affine:
        # a law that jumps (a Piecewise of the variables with constant pieces: a comparator) has a zero Jacobian
        # almost everywhere, yet is no affine function
        affine = not any(pw.free_symbols & variable for x in taus + dz for pw in x.atoms(*_STEPWISE))
    offset_fn, offset_varies, offset_uses_time, offset_coef_fn = None, False, False, None
    if affine:
        zero = {s: 0 for s in list(e) + list(de) + z + r}
        offsets = [x.subs(zero) for x in taus + dz]
        offset_varies = any(x.free_symbols & ({t} | set(input_syms)) for x in offsets)
        offset_uses_time = any(t in x.free_symbols for x in offsets)
        offset_fn = _lambdify(param_syms + input_syms + [t], offsets, where)
        if offset_varies and not offset_uses_time:
            coefs = [[sympy.diff(x, u) for u in input_syms] for x in offsets]
            if not any(cf.free_symbols & set(input_syms) for row in coefs for cf in row):
                offset_coef_fn = _lambdify(param_syms, coefs)
    tpl = Template(cls, k, states, params, inputs, fn, jac_entries, len(taus) + len(dz) + len(jac_exprs) + 1,
                   res_fn=_lambdify(args, taus + dz), jac_fn=_lambdify(args, jac_exprs),
                   affine=affine, offset_fn=offset_fn, offset_varies=offset_varies,
                   offset_uses_time=offset_uses_time, offset_coef_fn=offset_coef_fn,
                   surf_fn=_lambdify(args, surf) if surf else None, surf_codes=surf_codes,
                   exprs={"res": (args, taus + dz), "jac": (args, jac_exprs), **({"surf": (args, surf)} if surf else {})},
                   reads=reads)
    _TEMPLATES[key] = tpl
    return tpl


def _signature(tpl: Template) -> tuple:
    """What the compiled layout relies on in a template (checked when it is found again after unpickling)."""
    return (tpl.k, tuple(tpl.states), tuple(tpl.params), tuple(tpl.inputs), tuple(tpl.jac_entries), tpl.affine,
            tpl.offset_varies, tpl.offset_uses_time, tpl.surf_codes, tpl.reads)


class SignalBank:
    """The values of one signal parameter over all instances of a class, cheaply.

    Constant signals are evaluated once; a large set of ``Sine`` or ``Step``
    signals is evaluated with one numpy expression (same formula as
    ``Sine.value``/``Step.value``); any other signal by its own ``value``.
    """

    VECTORISE_FROM = 8   # below this a Python loop over math.sin is faster than numpy

    def __init__(self, signals: list):
        self.n = len(signals)
        self.values = np.zeros(self.n)
        self.const = all(type(s) is Constant for s in signals)
        for i, s in enumerate(signals):
            if type(s) is Constant:
                self.values[i] = s.value_
        self._loop = [(i, s) for i, s in enumerate(signals) if type(s) is not Constant]
        self._sine = self._step = None
        sines = [(i, s) for i, s in self._loop if type(s) is Sine]
        if len(sines) >= self.VECTORISE_FROM:
            idx = np.array([i for i, _ in sines])
            self._sine = (idx, *(np.array([getattr(s, a) for _, s in sines])
                                 for a in ("offset", "amplitude", "freq_hz", "phase", "start_time")))
            self._loop = [(i, s) for i, s in self._loop if type(s) is not Sine]
        steps = [(i, s) for i, s in self._loop if type(s) is Step]
        if len(steps) >= self.VECTORISE_FROM:
            idx = np.array([i for i, _ in steps])
            self._step = (idx, *(np.array([getattr(s, a) for _, s in steps])
                                 for a in ("offset", "height", "start_time")))
            self._loop = [(i, s) for i, s in self._loop if type(s) is not Step]

    @property
    def vectorised(self) -> bool:
        """Whether some of the signals are evaluated by one numpy expression (whose ``sin`` need not round as
        the C library's ``math.sin`` does: compiled code that must repeat these values leaves such a bank to
        ``at``)."""
        return self._sine is not None or self._step is not None

    def at(self, t: float, left: bool = False) -> np.ndarray:
        """Values at t (left limits when ``left``); the array is reused: copy to keep it."""
        vals = self.values
        for i, s in self._loop:
            vals[i] = s.value(t, left)
        if self._sine is not None:
            idx, off, amp, f, ph, t0 = self._sine
            on = t > t0 if left else t >= t0
            vals[idx] = off + on * (amp * np.sin(2.0 * math.pi * f * (t - t0) + ph))
        if self._step is not None:
            idx, off, h, t0 = self._step
            on = t > t0 if left else t >= t0
            vals[idx] = off + on * h
        return vals


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
        #: ``read_index[i, j]``: global state index that read input j of instance i takes (``compile.reads``)
        self.read_index = np.zeros((len(devices), len(tpl.reads)), np.int64)
        self.n = len(devices)
        pvals = []
        for p in tpl.params:
            vals = np.array([np.nan if d._values[p] is None else float(d._values[p]) for d in devices])
            pvals.append(vals)
        self.param_values = pvals
        self._scalar = {}           # id(numpy kernel) -> its float version or None (``call``)
        self.signals = [[d._values[p] for d in devices] for p in tpl.inputs]
        self.banks = [SignalBank(sigs) for sigs in self.signals]
        self.inputs_constant = all(b.const for b in self.banks)
        #: affine class whose offset tau(0) changes in time (e.g. a Torque with a Sine): evaluated per call
        self.offset_varies = tpl.affine and (tpl.offset_uses_time or (tpl.offset_varies and not self.inputs_constant))

    # -- pickling: the template's lambdified functions are not picklable (and a per-map Engine subclass
    # cannot be pickled by name), so the template is left out and found again from the first device
    # (``template_for``: the process-wide cache, lambdified once per class in the new process) on
    # first use after unpickling. ``__getattr__`` runs only when ``tpl`` is missing, so the hot path
    # (``g.tpl.res_fn``) costs nothing more.
    def __getstate__(self):
        state = self.__dict__.copy()
        state["_scalar"] = {}           # lambdified functions: found again on first use
        tpl = state.pop("tpl", None)
        if tpl is not None:
            state["_tpl_signature"] = _signature(tpl)
        return state

    def __getattr__(self, name):
        if name != "tpl" or "_tpl_signature" not in self.__dict__:
            raise AttributeError(name)
        tpl = template_for(self.devices[0])
        if _signature(tpl) != self._tpl_signature:
            dev = self.devices[0]
            raise ModelError(f"{type(dev).__name__} '{dev.name}': its class's laws differ from those it was "
                             f"compiled with before pickling (another version of the class or of regmech?); "
                             f"build and compile the model again in this process")
        self.tpl = tpl
        return tpl

    def inputs_at(self, t: float, left: bool = False) -> list[np.ndarray]:
        """Input values per signal parameter (fresh arrays)."""
        return [b.at(t, left).copy() for b in self.banks]

    def _inputs_now(self, t: float, left: bool) -> list[np.ndarray]:
        # the banks' own arrays: valid until the next evaluation, for callers that consume them at once
        return [b.at(t, left) for b in self.banks]

    def evaluate(self, e: np.ndarray, de: np.ndarray, z: np.ndarray, t: float, left: bool = False):
        """e, de: global compliant-row vectors; z: global state vector. Returns list of arrays."""
        tpl = self.tpl
        args = [e[self.row_index[:, r]] for r in range(tpl.k)] + \
               [de[self.row_index[:, r]] for r in range(tpl.k)] + \
               [z[self.state_index[:, s]] for s in range(len(tpl.states))] + \
               [z[self.read_index[:, j]] for j in range(len(tpl.reads))] + \
               self.param_values + self.inputs_at(t, left) + [t]
        out = tpl.fn(*args)
        return [np.broadcast_to(np.asarray(o, dtype=float), (self.n,)) for o in out]

    def call(self, fn, variables: list, t: float, left: bool = False):
        """``fn(variables..., params..., inputs..., t)`` for the template's ``res_fn``/``jac_fn``/``surf_fn``, the
        variables one array of the group's ``n`` instances each.

        A group of one instance evaluates the template's Python-float version (``Template.scalar``) and returns
        floats; where that raises (a division by zero, a domain error: the numpy kernel gives inf or NaN there,
        which the callers' checks report) or gives None (a ``Piecewise`` without a default), the numpy kernel
        answers. The outputs may share memory with the input buffers: consume them before the next call.
        """
        if self.n == 1:
            cache = self.__dict__.setdefault("_scalar", {})
            sfn = cache.get(id(fn), False)
            if sfn is False:
                sfn = cache[id(fn)] = self.tpl.scalar(fn)
            if sfn is not None:
                try:
                    out = sfn(*[float(v[0]) for v in variables], *[float(p[0]) for p in self.param_values],
                              *[float(b[0]) for b in self._inputs_now(t, left)], t)
                    if None not in out:
                        return out
                except (ArithmeticError, ValueError, TypeError):
                    pass                # this point only (a division by zero, a Piecewise without default)
                except Exception:       # noqa: BLE001 - a function the float printer does not know: never again
                    cache[id(fn)] = None
        return fn(*variables, *self.param_values, *self._inputs_now(t, left), t)

    def surfaces(self, e: np.ndarray, de: np.ndarray, z: np.ndarray, t: float, left: bool = False) -> np.ndarray:
        """The switching surfaces of every instance, shape (len(surf_codes), n) (``Device.switching_surfaces``)."""
        tpl = self.tpl
        args = [e[self.row_index[:, r]] for r in range(tpl.k)] + \
               [de[self.row_index[:, r]] for r in range(tpl.k)] + \
               [z[self.state_index[:, s]] for s in range(len(tpl.states))] + \
               [z[self.read_index[:, j]] for j in range(len(tpl.reads))]
        res = np.empty((len(tpl.surf_codes), self.n))
        for i, o in enumerate(self.call(tpl.surf_fn, args, t, left)):
            res[i] = o          # numpy broadcasts a constant surface
        return res

    def offsets(self, t: float, left: bool = False) -> np.ndarray:
        """Affine classes: ``[tau(0)..., dz(0)...]`` per instance, shape (k + ns, n)."""
        res = np.empty((self.tpl.k + len(self.tpl.states)) * self.n)
        self.offsets_into(res, 0, t, left)
        return res.reshape(-1, self.n)

    def offsets_into(self, buf: np.ndarray, start: int, t: float, left: bool = False) -> None:
        """Write ``offsets(t)`` row by row into ``buf[start:]`` (no allocation for the result)."""
        n = self.n
        for i, o in enumerate(self.tpl.offset_fn(*self.param_values, *self._inputs_now(t, left), t)):
            buf[start + i * n: start + (i + 1) * n] = o

    def constant_weights(self) -> np.ndarray:
        """Affine classes: the (constant) Jacobian entries, shape (n_jac, n)."""
        k, ns = self.tpl.k, len(self.tpl.states)
        zeros = [np.zeros(self.n)] * (2 * k + ns + len(self.tpl.reads))
        out = self.call(self.tpl.jac_fn, zeros, 0.0)
        res = np.empty((len(out), self.n))
        for i, o in enumerate(out):
            res[i] = o
        return res

    def evaluate_series(self, E: np.ndarray, DE: np.ndarray, Z: np.ndarray, T: np.ndarray, left: np.ndarray):
        """Vectorised over time: E (T x rows), returns list of (T x n) arrays."""
        tpl = self.tpl
        args = [E[:, self.row_index[:, r]] for r in range(tpl.k)] + \
               [DE[:, self.row_index[:, r]] for r in range(tpl.k)] + \
               [Z[:, self.state_index[:, s]] for s in range(len(tpl.states))] + \
               [Z[:, self.read_index[:, j]] for j in range(len(tpl.reads))] + \
               [p[None, :] for p in self.param_values] + \
               [np.array([[s.value(t, lf) for s in sigs] for t, lf in zip(T, left)]).reshape(len(T), self.n)
                for sigs in self.signals] + [T[:, None]]
        out = tpl.fn(*args)
        return [np.broadcast_to(np.asarray(o, dtype=float), (len(T), self.n)) for o in out]
