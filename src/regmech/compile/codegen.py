"""Compiled class kernels: a device class's symbolic laws printed as a numba C callback, once per class.

A device class states its law once, symbolically (``Device.laws``, ``derivatives``, ``switching_surfaces``);
``kernels.template_for`` differentiates it and keeps the expressions (``Template.exprs``). This module prints
those expressions as scalar code in a loop over the class's instances and compiles it with numba into a C
callback of one fixed signature,

    void kernel(double *a, int64 n, double t, double *out)

where ``a`` holds the ``n_args`` arguments of the template (``e``, ``de``, internal states ``z``, numeric
parameters, signal inputs; each a block of ``n`` values, instance ``i`` of argument ``j`` at ``a[j n + i]``)
and ``out`` receives the outputs, output ``o`` of instance ``i`` at ``out[o n + i]``. Three kernels per class:
``res`` (``[tau..., dz...]``), ``jac`` (the template's nonzero partial derivatives, in ``jac_entries`` order)
and ``surf`` (the switching surfaces). Because parameters are arguments, one compiled kernel serves every
model and every parameter set of the class: a sweep compiles nothing.

The printed source is written to a file in the kernel cache (``REGMECH_CACHE_DIR``, else
``$XDG_CACHE_HOME/regmech/kernels``, else ``~/.cache/regmech/kernels``) named by the hash of its text, and
imported from there with numba's on-disk cache on, so a later process loads the machine code instead of
compiling it again (first use of a class: about a second; afterwards a few milliseconds).

Where a law cannot be printed or compiled (a function numba does not know), ``class_kernels`` returns the
reason instead, and the class's devices stay on the Python path (``solvers.ida_native.eligible`` says which
class and why; a warning says so once per class).

Arithmetic: numba's ``error_model="numpy"`` (a division by zero gives inf or NaN, as the numpy kernels do,
and the callers' finiteness checks report it with the device's name).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import tempfile
import threading
import warnings

import sympy
from sympy.printing.pycode import PythonCodePrinter

#: the kernels of a template (``id``-keyed: templates live as long as the process), or the reason there are none
_KERNELS: dict = {}
_WARNED: set = set()
_LOCK = threading.Lock()
#: bump when the printed form changes in a way the printed text does not show (the numba signature, say)
_FORMAT = "1"


class _ScalarPrinter(PythonCodePrinter):
    """Scalar code numba compiles: ``math`` functions, float literals (numba unifies the branches of a
    conditional expression by type), small integer powers as products, a ``Piecewise`` without a default
    as NaN where no branch holds."""

    def __init__(self):
        super().__init__({"fully_qualified_modules": True, "standard": "python3"})

    def _print_Integer(self, expr):
        return f"{int(expr)}.0"

    def _print_Zero(self, expr):
        return "0.0"

    def _print_One(self, expr):
        return "1.0"

    def _print_NegativeOne(self, expr):
        return "-1.0"

    def _print_Rational(self, expr):
        return f"({int(expr.p)}.0/{int(expr.q)}.0)"

    def _print_Pow(self, expr, rational=False):
        base, exp = expr.base, expr.exp
        if exp.is_Integer and 1 <= abs(int(exp)) <= 8:
            b = self.parenthesize(base, 1000, strict=False) if not base.is_Atom else self._print(base)
            product = "*".join([f"({b})"] * abs(int(exp)))
            return f"({product})" if exp > 0 else f"(1.0/({product}))"
        if exp == sympy.Rational(1, 2):
            return f"math.sqrt({self._print(base)})"
        return f"(({self._print(base)})**({self._print(exp)}))"

    def _print_Piecewise(self, expr):
        pieces = list(expr.args)
        if pieces and pieces[-1].cond == sympy.true:
            out = f"({self._print(pieces.pop().expr)})"
        else:
            out = "math.nan"
        for piece in reversed(pieces):
            out = f"(({self._print(piece.expr)}) if ({self._print(piece.cond)}) else {out})"
        return out

    def _print_Heaviside(self, expr):
        x = self._print(expr.args[0])
        at0 = self._print(expr.args[1]) if len(expr.args) > 1 else "0.5"
        return f"(0.0 if ({x}) < 0.0 else (1.0 if ({x}) > 0.0 else {at0}))"

    def _print_sign(self, expr):
        x = self._print(expr.args[0])
        return f"(0.0 if ({x}) == 0.0 else math.copysign(1.0, {x}))"

    def _print_Abs(self, expr):
        return f"abs({self._print(expr.args[0])})"

    def _print_BooleanTrue(self, expr):
        return "True"

    def _print_BooleanFalse(self, expr):
        return "False"


def cache_dir() -> str:
    """The folder of the printed kernels (and, beside them, numba's cache of their machine code)."""
    base = os.environ.get("REGMECH_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "regmech")
    return os.path.join(base, "kernels")


def _body(args, exprs, n_out):
    """The loop body printing ``exprs`` (common subexpressions once) over instance ``i``."""
    names = {s: sympy.Symbol(f"v{j}") for j, s in enumerate(args[:-1])}
    names[args[-1]] = sympy.Symbol("t")
    exprs = [sympy.sympify(x).xreplace(names) for x in exprs]
    subs, reduced = sympy.cse(exprs, symbols=sympy.numbered_symbols("w"))
    printer = _ScalarPrinter()
    lines = [f"        v{j} = a[{j} * n + i]" for j in range(len(args) - 1)]
    lines += [f"        {printer.doprint(s)} = {printer.doprint(x)}" for s, x in subs]
    lines += [f"        o[{k} * n + i] = {printer.doprint(x)}" for k, x in enumerate(reduced)]
    if not lines:
        lines = ["        pass"]
    return "\n".join(lines), n_out


def _source(cls_name, parts):
    """The module text: one C callback per part ``(name, args, exprs)``."""
    out = [f'"""Compiled laws of {cls_name} (printed by regmech.compile.codegen; edit the class, not this file)."""',
           "import math",
           "from numba import carray, cfunc, types",
           "SIG = types.void(types.CPointer(types.float64), types.int64, types.float64, types.CPointer(types.float64))",
           ""]
    for name, args, exprs in parts:
        body, n_out = _body(args, exprs, len(exprs))
        out += ["",
                '@cfunc(SIG, cache=True, error_model="numpy")',
                f"def {name}(a_, n, t, o_):",
                f"    a = carray(a_, ({max(len(args) - 1, 1)} * n,))",
                f"    o = carray(o_, ({max(n_out, 1)} * n,))",
                "    for i in range(n):",
                body,
                ""]
    return "\n".join(out) + f"\n# format {_FORMAT}\n"


def _load(source):
    """Write ``source`` into the cache folder (once; named by its hash) and import it."""
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    folder = cache_dir()
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, f"k_{digest}.py")
    if not os.path.exists(path):
        # written under another name and renamed: a process reading it never sees half a file, and the file's
        # time stamp (numba's cache key) never changes afterwards
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        with os.fdopen(fd, "w") as fh:
            fh.write(source)
        os.replace(tmp, path)
    name = f"regmech_kernel_{digest}"
    module = sys.modules.get(name)
    if module is None:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        # importable by name while it runs: numba's cache records the module of each callback's globals and
        # imports it by that name when it loads the machine code again
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[name]
            raise
    return module


class ClassKernels:
    """The compiled ``res``, ``jac`` and ``surf`` callbacks of one template: their addresses (0: none) and
    argument and output counts."""

    def __init__(self, tpl, module):
        self.n_args = 2 * tpl.k + len(tpl.states) + len(tpl.params) + len(tpl.inputs)
        self.n_res = tpl.k + len(tpl.states)
        self.n_jac = len(tpl.jac_entries)
        self.n_surf = len(tpl.surf_codes)
        self.res = module.res.address
        self.jac = module.jac.address if self.n_jac else 0
        self.surf = module.surf.address if self.n_surf else 0
        self.module = module


def class_kernels(tpl):
    """The compiled kernels of template ``tpl`` (``ClassKernels``), or a string saying why it has none."""
    hit = _KERNELS.get(id(tpl))
    if hit is not None and hit[0] is tpl:
        return hit[1]
    with _LOCK:
        hit = _KERNELS.get(id(tpl))
        if hit is not None and hit[0] is tpl:
            return hit[1]
        out = _compile(tpl)
        _KERNELS[id(tpl)] = (tpl, out)
    if isinstance(out, str) and tpl.cls not in _WARNED:
        _WARNED.add(tpl.cls)
        warnings.warn(f"{tpl.cls.__name__}: its law is not compiled ({out}); its devices are evaluated in Python, "
                      f"which is slower but gives the same answers", RuntimeWarning, stacklevel=3)
    return out


def _compile(tpl):
    """``class_kernels`` computed: print, write, import, and compile each callback."""
    if tpl.exprs is None:
        return "its template keeps no expressions"
    parts = []
    for name in ("res", "jac", "surf"):
        if name in tpl.exprs:
            args, exprs = tpl.exprs[name]
            if exprs:
                parts.append((name, list(args), list(exprs)))
    try:
        source = _source(tpl.cls.__name__, parts)
    except Exception as exc:       # noqa: BLE001 - any printing failure means: not compiled, said by name
        return f"its law could not be printed as compiled code ({type(exc).__name__}: {exc})"
    try:
        module = _load(source)
        kernels = ClassKernels(tpl, module)
    except Exception as exc:       # noqa: BLE001 - numba's typing errors are long; the first line says it
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return f"numba could not compile it ({type(exc).__name__}: {first[:200]})"
    return kernels
