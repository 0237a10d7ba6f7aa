"""``regmech sweep``: a parameter study of a ready-made scene from the command line.

    regmech sweep coupled_clutches --param fn_max=10,20,40 --param t2=0.3,0.5 \\
        --t-end 1.5 --out study.csv [--executor serial|process|dask|tcp://host:port]

``--param NAME=v1,v2,...`` (or ``NAME=start:stop:count``, evenly spaced) names
a keyword argument of the scene function (``regmech scenes`` lists the
scenes); the study is the full factorial of the values (``--zipped``: k-th
values together). Outputs, unless ``--output SIGNAL`` names signals: the
final speed of every body (``<body>.w.final``) and the peak absolute torque
of every device that is not a source (``<device>.tau.max_abs``).
``--timeout-s S`` limits each run to S seconds (a run past it is a failed
row). Rows go to ``--out`` as they finish; rerunning the same command resumes. Exit status:
0 when every run succeeded, 1 when some failed, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import inspect
import sys

from ..errors import ParameterError, RegmechError


def parse_values(text: str) -> list:
    """``"10,20,40"`` -> [10, 20, 40]; ``"0.1:0.5:5"`` -> 5 evenly spaced values; true/false -> bool."""
    if text.count(":") == 2 and "," not in text:
        start, stop, count = text.split(":")
        n = int(count)
        if n < 1:
            raise ParameterError(f"--param range {text!r}: the count must be >= 1")
        a, b = float(start), float(stop)
        return [a + (b - a) * k / (n - 1) if n > 1 else a for k in range(n)]
    return [_value(v.strip()) for v in text.split(",") if v.strip() != ""]


def _value(text: str):
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="regmech sweep", description="parameter study of a ready-made scene",
                                epilog="outputs by default: final speeds of the bodies, peak torques of the "
                                       "devices (sources excluded)")
    p.add_argument("scene", help="scene name (regmech scenes lists them)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=v1,v2,...",
                   help="a scene parameter and its values (or NAME=start:stop:count); repeat for more")
    p.add_argument("--zipped", action="store_true", help="take the k-th values of all --param lists together")
    p.add_argument("--t-end", type=float, required=True, help="simulation end time [s]")
    p.add_argument("--dt-out", type=float, default=None, help="output interval [s] (default: t_end/500)")
    p.add_argument("--solver", default="auto", help="solver (default auto: chosen from the model and --accuracy)")
    p.add_argument("--accuracy", type=float, default=None,
                   help="bound of the global error of every run (relative to the range of each kind of state "
                        "signal; default 1e-3 with the auto solver, none with a named one)")
    p.add_argument("--rtol", type=float, default=None, help="relative tolerance (of a named --solver)")
    p.add_argument("--atol", type=float, default=None, help="absolute tolerance (of a named --solver)")
    p.add_argument("--output", action="append", default=None, metavar="SIGNAL",
                   help="report this signal's final value and peak instead of the defaults; repeat for more")
    p.add_argument("--out", required=True, help="result table (.csv, or .parquet with pyarrow)")
    p.add_argument("--executor", default="process",
                   help="serial, process (default), dask, or a Dask scheduler address tcp://host:port")
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: all CPUs)")
    p.add_argument("--timeout-s", type=float, default=None, metavar="SECONDS",
                   help="wall-clock limit of each run; a run past it is a failed row (default: none)")
    p.add_argument("--retry-failed", action="store_true", help="rerun the failed rows found in --out")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    try:
        return _run(args)
    except RegmechError as exc:
        print(f"regmech sweep: {exc}", file=sys.stderr)
        return 2


def _run(args) -> int:
    from regmech.library import SCENES

    from .outputs import SignalSummary, scene_defaults
    from .run import sweep
    build = SCENES.get(args.scene)
    if build is None:
        raise ParameterError(f"unknown scene {args.scene!r}; choose one of {sorted(SCENES)}")
    accepted = inspect.signature(build).parameters
    grid = {}
    for item in args.param:
        name, sep, values = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ParameterError(f"--param {item!r}: write NAME=v1,v2,... (e.g. --param fn_max=10,20,40)")
        if name not in accepted:
            raise ParameterError(f"scene {args.scene!r} has no parameter {name!r}; its parameters: {list(accepted)}")
        grid[name] = parse_values(values)
    if not grid:
        raise ParameterError("give at least one --param NAME=v1,v2,...")
    outputs = SignalSummary(args.output) if args.output else scene_defaults(build())
    options = {k: v for k, v in (("dt_out", args.dt_out), ("rtol", args.rtol), ("atol", args.atol),
                                 ("accuracy", args.accuracy)) if v is not None}
    table = sweep(build, grid, outputs, executor=args.executor, out=args.out, progress=not args.no_progress,
                  zipped=args.zipped, workers=args.workers, retry_failed=args.retry_failed,
                  timeout_s=args.timeout_s, t_end=args.t_end, solver=args.solver, **options)
    return _summary(table, args.out)


def _summary(table, out) -> int:
    attrs = table.attrs
    status = list(table["status"]) if hasattr(table, "iloc") else table.column("status")
    errors = list(table["error"]) if hasattr(table, "iloc") else table.column("error")
    n_failed = sum(s != "ok" for s in status)
    print(f"{len(status)} runs ({attrs['skipped']} found in {out}, {attrs['runs']} computed with "
          f"{attrs['executor']} x{attrs['workers']} in {attrs['elapsed']:.1f} s): {len(status) - n_failed} ok, "
          f"{n_failed} failed -> {out}")
    for s, e in zip(status, errors):
        if s != "ok":
            print(f"    failed: {e}")
            break
    if attrs["interrupted"]:
        return 130
    return 1 if n_failed else 0
