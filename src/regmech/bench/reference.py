"""Reference solutions of the benchmark scenes: computed once, cross-checked, cached on disk.

The reference of a scene is its *primary* method at a tight tolerance (see
``scenes``: DOP853 at rtol 1e-12, with the friction events located on its dense output).
A second, independent method (the *cross-check*) runs the same scene; its
difference from the primary, measured with the same metrics as every other
run (``metrics.compare``), is the resolution of the reference: errors of the
benchmarked runs below about that value are not resolved. When the
difference exceeds ``DISAGREE_MAX_REL`` (or the two take different paths
through the friction modes) the report says that the reference is in doubt.
If the primary method fails, the cross-check method is used as the
reference and the report says so.

Cache: ``<cache_dir>/<key>.npz`` with ``key`` the first 20 hex digits of the
SHA-256 of the scene's builder name, parameters, ``t_end``, ``dt_out``, the
compared signals, both reference methods with their options and the regmech
version (``reference_key``). The default folder is ``$REGMECH_CACHE/ref`` or
``~/.cache/regmech/ref``.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .guard import classify_error, time_limit
from .metrics import Errors, Trace, compare, trace_of

#: a cross-check difference above this (max relative error) puts the reference in doubt
DISAGREE_MAX_REL = 1e-6
#: ... and a switch-time difference above this [s]
DISAGREE_SWITCH = 1e-6


def default_cache_dir() -> Path:
    root = os.environ.get("REGMECH_CACHE")
    return (Path(root) if root else Path.home() / ".cache" / "regmech") / "ref"


def method_label(method) -> str:
    solver, opts = method
    return f"{solver} " + " ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in opts.items())


def reference_key(scene) -> str:
    """Hash of everything the reference depends on (module docstring)."""
    import regmech
    spec = {"scene": scene.scene, "params": [[k, repr(v)] for k, v in scene.params], "t_end": scene.t_end,
            "dt_out": scene.dt_out, "signals": list(scene.signal_names()),
            "methods": [[s, sorted((k, repr(v)) for k, v in o.items())] for s, o in scene.references()],
            "regmech": regmech.__version__}
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:20]


@dataclass
class Reference:
    scene_key: str
    key: str
    primary: str                 # label of the method that gave ``trace``
    check: str                   # label of the cross-check method ("" when it failed)
    trace: Trace
    cross: Errors | None         # the cross-check's errors against ``trace`` (None when it failed)
    wall_primary: float
    wall_check: float
    note: str = ""               # failures of a reference method, fallbacks
    cached: bool = False

    @property
    def in_doubt(self) -> bool:
        if self.cross is None:
            return True
        if not self.cross.max_rel <= DISAGREE_MAX_REL:
            return True
        sw = self.cross.switch
        return sw is not None and (not sw.consistent or (sw.matched and sw.max_dt > DISAGREE_SWITCH))

    def summary(self) -> str:
        if self.cross is None:
            return f"{self.primary}; no cross-check ({self.note})"
        text = f"{self.primary}; cross-check {self.check}: max rel diff {self.cross.max_rel:.2e}"
        if self.cross.switch is not None:
            sw = self.cross.switch
            text += f", switch times {sw.max_dt:.1e} s ({sw.matched} matched, {sw.unmatched} unmatched)"
        return text + (" -- DISAGREE: reference in doubt" if self.in_doubt else "")


def _run(scene, method, grid, limit):
    solver, opts = method
    model = scene.build()
    t0 = time.perf_counter()
    with time_limit(limit):
        res = model.simulate(scene.t_end, dt_out=scene.dt_out, solver=solver, **opts)
    wall = time.perf_counter() - t0
    return trace_of(res, scene.signal_names(), grid), wall, model


def compute_reference(scene, time_limit_s: float | None = 3600.0) -> Reference:
    """Run both reference methods of ``scene`` (no cache)."""
    from regmech.solvers.common import output_grid
    grid = output_grid(0.0, scene.t_end, scene.dt_out)
    primary, check = scene.references()
    traces, walls, notes = {}, {}, []
    for role, method in (("primary", primary), ("check", check)):
        try:
            traces[role], walls[role], _ = _run(scene, method, grid, time_limit_s)
        except BaseException as exc:            # noqa: BLE001 - recorded; KeyboardInterrupt goes on
            if isinstance(exc, KeyboardInterrupt):
                raise
            status, reason = classify_error(exc, scene.build())
            notes.append(f"{role} {method_label(method)} {status}: {reason}")
    if "primary" not in traces and "check" not in traces:
        raise ReferenceUnavailable(f"no reference for scene '{scene.key}': " + "; ".join(notes))
    if "primary" in traces:
        main, main_label = traces["primary"], method_label(primary)
        other = traces.get("check")
        other_label = method_label(check) if other is not None else ""
    else:
        main, main_label = traces["check"], method_label(check) + " (primary failed)"
        other, other_label = None, ""
    cross = compare(other, main, with_switches=scene.stick_slip) if other is not None else None
    return Reference(scene.key, reference_key(scene), main_label, other_label, main, cross,
                     walls.get("primary", float("nan")), walls.get("check", float("nan")), "; ".join(notes))


class ReferenceUnavailable(Exception):
    """Both reference methods failed (the scene's runs are then reported without errors)."""


def _save(path: Path, ref: Reference) -> None:
    meta = {"scene_key": ref.scene_key, "key": ref.key, "primary": ref.primary, "check": ref.check,
            "wall_primary": ref.wall_primary, "wall_check": ref.wall_check, "note": ref.note,
            "cross": None if ref.cross is None else {
                "max_rel": ref.cross.max_rel, "worst": ref.cross.worst_signal, "final": ref.cross.final,
                "switch": None if ref.cross.switch is None else [ref.cross.switch.max_dt, ref.cross.switch.matched,
                                                                 ref.cross.switch.unmatched]}}
    arrays = {f"ref_{k}": v for k, v in ref.trace.to_arrays().items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, meta=np.array(json.dumps(meta)), **arrays)
    os.replace(tmp, path)


def _load(path: Path) -> Reference:
    from .metrics import SwitchError
    with np.load(path, allow_pickle=False) as d:
        meta = json.loads(str(d["meta"]))
        trace = Trace.from_arrays({k[4:]: d[k] for k in d.files if k.startswith("ref_")})
    cr = meta["cross"]
    cross = None
    if cr is not None:
        sw = None if cr["switch"] is None else SwitchError(float(cr["switch"][0]), int(cr["switch"][1]),
                                                           int(cr["switch"][2]))
        cross = Errors(float(cr["max_rel"]), cr["worst"], float(cr["final"]), sw)
    return Reference(meta["scene_key"], meta["key"], meta["primary"], meta["check"], trace, cross,
                     meta["wall_primary"], meta["wall_check"], meta["note"], cached=True)


def get_reference(scene, cache_dir: Path | None = None, use_cache: bool = True,
                  time_limit_s: float | None = 3600.0) -> Reference:
    """The scene's reference from the cache, or computed (and cached)."""
    cache_dir = default_cache_dir() if cache_dir is None else Path(cache_dir)
    path = cache_dir / f"{scene.key}-{reference_key(scene)}.npz"
    if use_cache and path.exists():
        try:
            return _load(path)
        except (OSError, KeyError, ValueError):
            pass                                  # a damaged cache file is recomputed
    ref = compute_reference(scene, time_limit_s)
    if use_cache:
        _save(path, ref)
    return ref
