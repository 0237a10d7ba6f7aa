"""Parameter sets of a study: grids, Latin hypercube samples, scatter around a nominal point.

Every sampler returns a list of dicts (one parameter set per run, in run-id
order), which ``sweep`` takes as it is; ``runs_from`` turns any accepted
``params`` form (a grid dict, a pandas DataFrame, an iterable of dicts) into
that list.
"""

from __future__ import annotations

import itertools
import math
from typing import Iterable, Mapping

import numpy as np

from ..errors import ParameterError

#: column names of the study table that a parameter may not take
RESERVED = ("run_id", "status", "error", "wall_time")


def grid(params: Mapping[str, Iterable], zipped: bool = False) -> list[dict]:
    """Parameter sets of a grid: the full factorial of the lists (last name varies fastest),
    or with ``zipped=True`` the k-th values of all lists together (equal lengths).

    >>> grid({"fn_max": [10, 20], "t2": [0.3, 0.4]})
    [{'fn_max': 10, 't2': 0.3}, {'fn_max': 10, 't2': 0.4}, {'fn_max': 20, 't2': 0.3}, {'fn_max': 20, 't2': 0.4}]
    """
    names = list(params)
    values = []
    for name in names:
        vals = params[name]
        if isinstance(vals, (str, bytes)) or not isinstance(vals, Iterable):
            vals = [vals]              # a single value is a one-point axis
        vals = [_plain(v) for v in vals]
        if not vals:
            raise ParameterError(f"grid: parameter '{name}' has no values; give at least one")
        values.append(vals)
    if zipped:
        lengths = {name: len(v) for name, v in zip(names, values)}
        if len(set(lengths.values())) > 1:
            raise ParameterError(f"grid(zipped=True): the value lists must have equal lengths, got {lengths}")
        combos = zip(*values)
    else:
        combos = itertools.product(*values)
    return [dict(zip(names, c)) for c in combos]


def latin_hypercube(bounds: Mapping[str, tuple[float, float]], n: int, seed=None) -> list[dict]:
    """``n`` parameter sets of a Latin hypercube sample of the box ``bounds`` (name -> (low, high)).

    Each range is cut into ``n`` equal strata and each stratum holds exactly
    one sample: ``x = low + (high - low) * (perm_k + u_k) / n`` with a random
    permutation ``perm`` per parameter and ``u ~ U(0, 1)``. The same ``seed``
    gives the same sample.
    """
    n = _count(n, "latin_hypercube")
    rng = np.random.default_rng(seed)
    columns = {}
    for name, bound in bounds.items():
        try:
            low, high = (float(b) for b in bound)
        except (TypeError, ValueError):
            raise ParameterError(f"latin_hypercube: bounds of '{name}' must be (low, high) numbers, "
                                 f"got {bound!r}") from None
        if not (math.isfinite(low) and math.isfinite(high) and high >= low):
            raise ParameterError(f"latin_hypercube: bounds of '{name}' must be finite with low <= high, "
                                 f"got ({low}, {high})")
        strata = (rng.permutation(n) + rng.random(n)) / n
        columns[name] = low + (high - low) * strata
    return [{name: float(col[k]) for name, col in columns.items()} for k in range(n)]


def scatter(nominal: Mapping[str, float], rel_sd=None, abs_sd=None, n: int = 100, seed=None,
            dist: str = "normal") -> list[dict]:
    """``n`` parameter sets scattered around ``nominal`` (a Monte Carlo tolerance study).

    The standard deviation of parameter p is ``rel_sd * |nominal_p|`` or
    ``abs_sd`` (each a number for all parameters or a dict per parameter;
    parameters without either stay at their nominal value).
    ``dist="normal"``: ``x = nominal + sd * N(0, 1)``; ``dist="uniform"``:
    ``x ~ U(nominal - sqrt(3) sd, nominal + sqrt(3) sd)``, the uniform
    distribution with the same standard deviation. The same ``seed`` gives the
    same sample; a sample may leave a parameter's legal range (e.g. a negative
    inertia): such runs are reported as failed, not dropped.
    """
    n = _count(n, "scatter")
    if (rel_sd is None) == (abs_sd is None):
        raise ParameterError("scatter: give exactly one of rel_sd (relative) or abs_sd (absolute) standard deviation")
    if dist not in ("normal", "uniform"):
        raise ParameterError(f"scatter: dist must be 'normal' or 'uniform', got {dist!r}")
    rng = np.random.default_rng(seed)
    columns = {}
    for name, x0 in nominal.items():
        x0 = float(x0)
        spec = rel_sd if rel_sd is not None else abs_sd
        sd = spec.get(name) if isinstance(spec, Mapping) else spec
        if sd is None:
            columns[name] = np.full(n, x0)
            continue
        sd = float(sd) * (abs(x0) if rel_sd is not None else 1.0)
        if not (math.isfinite(sd) and sd >= 0):
            raise ParameterError(f"scatter: the standard deviation of '{name}' must be finite and >= 0, got {sd}")
        if dist == "normal":
            columns[name] = x0 + sd * rng.standard_normal(n)
        else:
            columns[name] = x0 + sd * math.sqrt(3.0) * rng.uniform(-1.0, 1.0, n)
    return [{name: float(col[k]) for name, col in columns.items()} for k in range(n)]


def runs_from(params, zipped: bool = False) -> list[dict]:
    """The parameter sets of a study, in run-id order, from any accepted ``params`` form."""
    if isinstance(params, Mapping):
        runs = grid(params, zipped=zipped)
    elif _is_dataframe(params):
        runs = [{str(k): _plain(v) for k, v in rec.items()} for rec in params.to_dict(orient="records")]
    else:
        if zipped:
            raise ParameterError("sweep(zipped=True) applies to a grid (a dict of lists), not to a sample")
        try:
            runs = [dict(p) for p in params]
        except (TypeError, ValueError):
            raise ParameterError("sweep: params must be a dict of value lists (a grid), a pandas DataFrame or an "
                                 "iterable of dicts (one parameter set per run)") from None
        runs = [{str(k): _plain(v) for k, v in p.items()} for p in runs]
    if not runs:
        raise ParameterError("sweep: the study has no parameter sets")
    for name in set().union(*runs):
        if name in RESERVED:
            raise ParameterError(f"sweep: a parameter may not be called '{name}' (a column of the result table); "
                                 f"rename it in the build function")
    return runs


def _plain(value):
    """numpy scalars -> Python scalars, so that component parameter checks accept them."""
    return value.item() if isinstance(value, np.generic) else value


def _is_dataframe(obj) -> bool:
    return type(obj).__name__ == "DataFrame" and hasattr(obj, "to_dict")


def _count(n, who: str) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"{who}: n must be a positive integer, got {n!r}")
    return int(n)
