"""Pickling a user's function by value: a model whose signal is a lambda pickles.

``pickle`` saves a function by reference (its module and qualified name), so a lambda, or a function
defined inside another, cannot be pickled: there is no name to look it up by. A model that keeps
one as a signal (``Torque("drive", tau=lambda t: ...)``) would then fail to pickle with a bare
``PicklingError`` that names neither the component nor the signal.

``portable(func, label)`` is what the signal pickles instead of such a function: its code (``marshal``,
read back by the same Python version), the globals its code names (modules by name, functions again by
value where they have no name to be found by), its defaults and the values of its closure. Unpickled,
it is a new function that computes the same values. Anything the function refers to that cannot be
pickled (an open file, a lock) is a ``SignalPicklingError`` naming the signal and what to change.
"""

from __future__ import annotations

import builtins
import functools
import importlib
import marshal
import pickle
import sys
import types

from .errors import RegmechError

#: nesting of functions pickled by value inside one another (a closure over a closure ...)
MAX_DEPTH = 20


class SignalPicklingError(RegmechError, pickle.PicklingError):
    """A signal's callable that cannot be pickled (also a ``pickle.PicklingError``)."""


def _by_reference(func) -> bool:
    """Whether plain pickle finds ``func`` by its module and qualified name."""
    module = sys.modules.get(getattr(func, "__module__", None) or "")
    obj = module
    for part in (getattr(func, "__qualname__", "") or "").split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            return False
    return obj is func


def _code_names(code) -> set:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


class _Module:
    """A module, pickled by its name."""

    def __init__(self, name):
        self.name = name

    def __reduce__(self):
        return importlib.import_module, (self.name,)


def _value(obj, label, depth):
    """``obj`` ready for pickle: modules by name, functions without a name by value, the rest as it is."""
    if isinstance(obj, types.ModuleType):
        return _Module(obj.__name__)
    if isinstance(obj, types.FunctionType) and not _by_reference(obj):
        return _ByValue(obj, label, depth + 1)
    if isinstance(obj, functools.partial):
        return functools.partial(_value(obj.func, label, depth), *obj.args, **obj.keywords)
    return obj


class _ByValue:
    """A function pickled by value (module docstring)."""

    def __init__(self, func, label, depth=0):
        if depth > MAX_DEPTH:
            raise SignalPicklingError(f"{label}: the callable {func.__qualname__} refers to functions nested more "
                                      f"than {MAX_DEPTH} deep; define it at module level (def) so that pickle finds "
                                      f"it by name")
        self.func, self.label, self.depth = func, label, depth

    def __reduce__(self):
        f, label, depth = self.func, self.label, self.depth
        g = f.__globals__
        names = sorted(n for n in _code_names(f.__code__) if n in g)
        cells = None if f.__closure__ is None else tuple(_value(c.cell_contents, label, depth) for c in f.__closure__)
        return _rebuild, (marshal.dumps(f.__code__), f.__name__, f.__qualname__, f.__module__,
                          {n: _value(g[n], label, depth) for n in names},
                          f.__defaults__, f.__kwdefaults__, cells)


def _rebuild(code, name, qualname, module, globals_, defaults, kwdefaults, cells):
    g = {"__builtins__": builtins, "__name__": module}
    g.update(globals_)
    func = types.FunctionType(marshal.loads(code), g, name, defaults,
                              None if cells is None else tuple(types.CellType(v) for v in cells))
    func.__kwdefaults__ = kwdefaults
    func.__qualname__ = qualname
    func.__module__ = module
    return func


def portable(func, label: str):
    """What a signal pickles for its callable ``func`` (``label`` names the signal in errors): ``func`` itself
    when pickle finds it by name, else a picklable stand-in (module docstring). A stand-in whose parts do not
    pickle is a ``SignalPicklingError`` naming the signal."""
    try:
        out = _value(func, label, 0)
    except SignalPicklingError:
        raise
    if out is func and isinstance(func, types.FunctionType):
        return func
    try:
        pickle.dumps(out)
    except SignalPicklingError:
        raise
    except Exception as exc:
        raise SignalPicklingError(
            f"{label}: the callable {getattr(func, '__qualname__', None) or repr(func)} cannot be pickled ({exc}); "
            f"a pickled model (a saved one, a process pool's, Dask's) carries its signals: give a callable that "
            f"refers only to picklable objects (numbers, arrays, modules, functions), define it at module level "
            f"(def), or use a regmech.signals signal (Step, Ramp, Sine, Table, ...)") from exc
    return out
