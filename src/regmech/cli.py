"""Command line: ``regmech demo``, ``regmech modes``, ``regmech scenes``, ``regmech check``, ``regmech draw``.

``regmech draw SCENE|FILE.py [--out FILE.png]`` writes the dynamic scheme
(``Model.draw``): masses as blocks, the devices between them by kind.

``regmech check SCENE|FILE.py [--summary]`` prints the regularity report of a
scene or of the models a Python file defines (exit status 1 when a model
breaks a rule, the message naming the components and the fix).

``regmech demo --out DIR`` simulates ready-made drivetrain scenes (MSL
First: motor, gear, elastic load; CoupledClutches: stick/slip; a car's
launch through a slipping clutch) with ``--solver`` (default ``auto``) at
``--accuracy`` (default 1e-3), checks them against the MSL reference data
when it is found next to the checkout, and writes CSV results and PNG plots
to DIR.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def _demo(args) -> int:
    from regmech.library import coupled_clutches, first, vehicle_launch
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = [
        ("first", first(), 1.0, ["inertia1.w", "inertia2.w", "inertia3.w"], ["spring.tau", "idealGear.tau"], None),
        ("coupled_clutches", coupled_clutches(), 1.5, ["J1.w", "J2.w", "J3.w", "J4.w"],
         ["clutch1.tau", "clutch2.tau", "clutch3.tau"], None),
        ("vehicle_launch", vehicle_launch(), 3.0, ["flywheel.w", "gearbox_in.w", "wheel_left.J.w", "body.v"],
         ["clutch.tau", "driveshaft.tau"], {"w": "rpm", "v": "km/h"}),
    ]
    for name, model, t_end, speeds, torques, units in runs:
        t0 = time.perf_counter()
        opts = {"rtol": args.rtol} if args.rtol is not None else {}
        # --rtol sets a named solver's tolerance: with the default auto it means IDA's (as before auto)
        solver = "ida" if opts and args.solver == "auto" else args.solver
        res = model.simulate(t_end, dt_out=5e-4, solver=solver, accuracy=args.accuracy, **opts)
        wall = time.perf_counter() - t0
        csv_path = out / f"{name}.csv"
        res.to_csv(csv_path, speeds + torques + [n for n in res.names if n.endswith(".mode")])
        png_path = out / f"{name}.png"
        from regmech.errors import RegmechError
        try:
            # one axis per unit (speeds, torques), a mode strip per friction device, the mode changes numbered
            # and listed under the plot: a reader needs no code to follow it
            res.plot(speeds + torques, path=png_path, events="annotate", units=units,
                     title=f"{model.name}: {t_end:g} s, {res.stats.solver}")
        except RegmechError:                 # matplotlib missing
            png_path = None
        load = res.stats.load_time()        # numba's kernels, once per process
        loaded = f" + {load:.1f} s loading the compiled kernels" if load else ""
        print(f"{model.name}: simulated {t_end} s in {(wall - load) * 1e3:.0f} ms{loaded} ({res.stats.rhs_calls} "
              f"residual calls, {len(res.events)} mode changes)")
        print(f"    {res.stats}")
        for ev in res.events:
            print(f"    {ev}")
        print(f"    results: {csv_path}")
        if png_path:
            print(f"    plot:    {png_path}")
        else:
            print("    (no plot: pip install 'regmech[plot]')")
        _compare_reference(name, res)
    return 0


def _compare_reference(name, res):
    import numpy as np
    from regmech.data import msl_dir
    file = {"first": "First.csv", "coupled_clutches": "CoupledClutches.csv"}.get(name)
    if file is None:
        return
    path = msl_dir() / file
    if not path.exists():
        # only when $REGMECH_MSL_REFERENCE names a folder without the file: say so, never skip silently
        print(f"    (no MSL comparison: {path} not found)")
        return
    ref = np.genfromtxt(path, delimiter=",", names=True)
    cols = {"first": [("inertia3.w", "inertia3w"), ("damper.w_rel", "damperw_rel")],
            "coupled_clutches": [("J1.w", "J1w"), ("clutch1.w_rel", "clutch1w_rel"),
                                 ("clutch3.w_rel", "clutch3w_rel")]}[name]
    errs = ", ".join(f"{n} {np.max(np.abs(np.interp(ref['time'], res.t, res[n]) - ref[c])):.2e}" for n, c in cols)
    print(f"    max abs deviation from the MSL reference (tube 2e-3): {errs}")


def _scenes(args) -> int:
    from regmech.library import SCENES
    for name, fn in SCENES.items():
        doc = (fn.__doc__ or "").strip().splitlines()[0] if fn.__doc__ else ""
        print(f"{name:20s} {doc}")
    return 0


def _load_models(target: str):
    """The models named by ``target``: a library scene name, or a Python file whose module-level
    ``Model`` objects are taken (or, when it defines none, the Model returned by a function ``build``,
    ``model`` or ``make_model`` called without arguments). The file runs with ``__name__`` set to
    ``"__regmech_check__"``, so its ``if __name__ == "__main__":`` part (a simulation, plots) does not."""
    import runpy
    from regmech.errors import RegmechError
    from regmech.library import SCENES
    from regmech.model import Model
    if target in SCENES:
        return [SCENES[target]()]
    path = Path(target)
    if not path.suffix == ".py":
        raise RegmechError(f"'{target}' is neither a scene ({', '.join(sorted(SCENES))}) nor a .py file")
    if not path.is_file():
        raise RegmechError(f"no file '{target}'")
    env = runpy.run_path(str(path), run_name="__regmech_check__")
    models = [v for k, v in env.items() if isinstance(v, Model) and not k.startswith("_")]
    if not models:
        for name in ("build", "model", "make_model"):
            fn = env.get(name)
            if callable(fn):
                out = fn()
                if isinstance(out, Model):
                    return [out]
        raise RegmechError(f"'{target}' defines no Model at module level and no build()/model()/make_model() "
                           f"function returning one; assign the model to a variable, e.g. m = rm.Model(...)")
    return list({id(m): m for m in models}.values())


def _check(args) -> int:
    import warnings
    from regmech.errors import ModelError
    models = _load_models(args.target)
    status = 0
    for model in models:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")      # a stretched spectrum is listed in the report instead
                report = model.summary() if args.summary else model.check()
            print(report)
        except ModelError as exc:                    # regularity, structure: the model has to change
            print(f"Model '{model.name}': PROBLEMS\n  {exc}")
            status = 1
    return status


def _draw(args) -> int:
    """``regmech draw SCENE|FILE.py --out FILE.png``: the dynamic scheme of a scene or of the models of a
    file (several models: FILE-<model>.png)."""
    models = _load_models(args.target)
    out = Path(args.out)
    for model in models:
        path = out if len(models) == 1 else out.with_name(f"{out.stem}-{model.name}{out.suffix or '.png'}")
        model.draw(path=path)
        print(f"{model.name}: {len(model.components)} components, scheme written to {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "modes":
        from regmech.analysis.cli import modes_main
        return modes_main(argv[1:])
    if argv and argv[0] in ("bench", "sweep"):
        try:
            mod = __import__(f"regmech.bench.cli", fromlist=["main"]) if argv[0] == "bench" else \
                __import__("regmech.sweep", fromlist=["main"])
        except ImportError:
            print(f"regmech {argv[0]}: not available in this version", file=sys.stderr)
            return 2
        return mod.main(argv[1:])
    parser = argparse.ArgumentParser(prog="regmech", description="regular mechanical systems: drivetrain dynamics")
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("demo", help="simulate ready-made drivetrain scenes, write CSV and PNG")
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--solver", default="auto", help="solver (default auto: chosen from the model and --accuracy)")
    p.add_argument("--accuracy", type=float, default=None,
                   help="bound of the estimated global error (relative to the range of each kind of state "
                        "signal; default 1e-3 with the auto solver)")
    p.add_argument("--rtol", type=float, default=None, help="relative tolerance of a named --solver (with auto: IDA's)")
    p.set_defaults(func=_demo)
    p = sub.add_parser("check", help="regularity check and summary of a scene or of the models in a .py file")
    p.add_argument("target", help="scene name (regmech scenes lists them) or a Python file defining a Model")
    p.add_argument("--summary", action="store_true", help="list the components by name (m.summary())")
    p.set_defaults(func=_check)
    p = sub.add_parser("draw", help="draw the dynamic scheme of a scene or of the models in a .py file (PNG)")
    p.add_argument("target", help="scene name (regmech scenes lists them) or a Python file defining a Model")
    p.add_argument("--out", default=None, help="image file (.png, .svg, .pdf; default: <target>.png)")
    p.set_defaults(func=_draw)
    p = sub.add_parser("scenes", help="list the ready-made scenes")
    p.set_defaults(func=_scenes)
    sub.add_parser("modes", help="natural frequencies and mode shapes of a scene (regmech modes -h)")
    sub.add_parser("sweep", help="parameter study of a scene (regmech sweep -h)")
    sub.add_parser("bench", help="work-precision benchmark of the solvers (regmech bench -h)")
    args = parser.parse_args(argv)
    if args.cmd == "draw" and args.out is None:
        args.out = f"{Path(args.target).stem}.png"
    from regmech.errors import RegmechError
    try:
        return args.func(args)
    except RegmechError as exc:         # a refused option or model: the message, not a traceback
        print(f"regmech {args.cmd}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
