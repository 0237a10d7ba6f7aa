"""``regmech modes <scene> [--k N] [--out DIR]``: natural frequencies and mode shapes of a scene.

Prints the undamped and damped natural frequencies and the mode-shape table
(mode x mass); with ``--out`` writes ``modes.csv``, ``mode_shapes.csv``,
``mode_shapes.png`` and, when the scene has an input (a Torque, Force,
Position or Speed source), ``response.png``: the harmonic response of the
mass speeds to a unit amplitude of the first input, natural frequencies
marked; with ``--orders`` (or for a scene with an ``Engine``)
``campbell.png`` and ``campbell.csv``: natural frequencies and engine
orders against speed, the resonance speeds where they cross.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="regmech modes",
                                description="natural frequencies, damping and mode shapes of a ready-made scene")
    p.add_argument("scene", help="scene name (regmech scenes lists them)")
    p.add_argument("--k", type=int, default=None, help="number of lowest modes (default: all)")
    p.add_argument("--out", default=None, help="folder for CSV tables and PNG plots")
    p.add_argument("--t", type=float, default=0.0,
                   help="time of the operating point [s] (default 0: the scene's start values); > 0: the scene "
                        "is simulated to that instant and linearised where the run is (state and friction modes)")
    p.add_argument("--mode", action="append", default=[], metavar="DEVICE=MODE",
                   help="friction mode at the operating point, e.g. clutch1=Stuck (repeatable; overrides the "
                        "run's or the start's mode of that device)")
    p.add_argument("--fmax", type=float, default=None, help="upper frequency of the response plot [Hz]")
    p.add_argument("--orders", default=None, metavar="K1,K2,...",
                   help="engine orders for the Campbell diagram (campbell.png, campbell.csv with --out), e.g. "
                        "1,2,4; default for a scene with an Engine: 0.5,1,1.5,2,3,4 (a four-stroke engine)")
    p.add_argument("--speed", default=None, metavar="LOW:HIGH",
                   help="engine speed range of the Campbell diagram [rpm] (default: the speeds of the Engine's "
                        "torque map, else 500:6000)")
    return p


def modes_main(argv: list[str]) -> int:
    """Entry point of ``regmech modes``; returns the exit status (0 ok, 2 error)."""
    from ..errors import RegmechError
    from ..library import SCENES
    from .harmonic import harmonic_response
    from .modal import modal

    args = _parser().parse_args(argv)
    builder = SCENES.get(args.scene)
    if builder is None:
        print(f"regmech modes: unknown scene '{args.scene}'; scenes: {', '.join(sorted(SCENES))}", file=sys.stderr)
        return 2
    try:
        modes = dict(item.split("=", 1) for item in args.mode) if args.mode else None
    except ValueError:
        print("regmech modes: --mode takes DEVICE=MODE, e.g. clutch1=Stuck", file=sys.stderr)
        return 2
    try:
        model = builder()
        run = None
        if args.t < 0 or not np.isfinite(args.t):
            print(f"regmech modes: --t is a time >= 0 [s], got {args.t}", file=sys.stderr)
            return 2
        if args.t > 0:
            run = model.simulate(args.t)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            lin = model.linearize(t=args.t, modes=modes, at=run)
        result = modal(lin, k=args.k)
        _orders_and_speeds(model, args.orders, args.speed)     # bad --orders/--speed: refused before printing
        print(dof_line(model.name, lin))
        print(operating_line(lin, run, modes))
        for w in caught:
            print(f"note: {w.message}")
        print()
        print(result)
        if args.out:
            out = Path(args.out)
            out.mkdir(parents=True, exist_ok=True)
            result.frequency_table().to_csv(out / "modes.csv")
            result.table().to_csv(out / "mode_shapes.csv")
            print(f"\ntables: {out / 'modes.csv'}, {out / 'mode_shapes.csv'}")
            _plots(result, lin, out, args.fmax, harmonic_response)
            _campbell(result, model, out, args.orders, args.speed)
    except RegmechError as exc:
        print(f"regmech modes: {exc}", file=sys.stderr)
        return 2
    return 0


def operating_line(lin, run=None, asked=None) -> str:
    """Where the model was linearised: the start values or the run to ``lin.t`` (its solver), and the
    friction mode of every friction device there (with the time it entered that mode in the run, and
    ``(asked)`` for modes given with ``--mode``)."""
    from ..modes import MODE_NAMES
    where = (f"operating point: the run to t={lin.t:g} s ({run.stats.solver}, {len(run.events)} mode changes)"
             if run is not None else f"operating point: the start values at t={lin.t:g} s")
    rows = lin.compiled.structure.friction
    if not rows:
        return where + "; no friction devices"
    parts, seen = [], set()
    for row, code in zip(rows, lin.modes):
        name = row.device.name
        if name in seen:
            continue
        seen.add(name)
        text = f"{name} {MODE_NAMES.get(int(code), code)}"
        if asked and name in asked:
            text += " (asked)"
        elif run is not None:
            since = [ev.t for ev in run.events if ev.component == name and ev.kind == "mode" and ev.t <= lin.t]
            if since:
                text += f" (since {since[-1]:.4g} s)"
        parts.append(text)
    return where + "; friction modes: " + ", ".join(parts)


def dof_line(name: str, lin) -> str:
    """The head line of ``regmech modes``: the degrees of freedom (the independent coordinates the modes
    are computed in, one per undamped mode) and the masses (the columns of the mode-shape table, more
    when gears or rigid links make some masses follow others)."""
    coords = list(lin.coords)
    shown = ", ".join(coords[:8]) + (f", ... ({len(coords)})" if len(coords) > 8 else "")
    masses = len(lin.mass_coordinates())
    follow = "" if masses == lin.n else \
        f"; the mode-shape table has all {masses} masses, {masses - lin.n} of them moving with these through gears or rigid links"
    return (f"{name}: {lin.n} degrees of freedom, so {lin.n} modes (independent coordinates {shown}{follow}); "
            f"inputs {lin.all_inputs or 'none'}")


def _plots(result, lin, out: Path, fmax, harmonic_response) -> None:
    from ..errors import RegmechError
    from .plots import plot_mode_shapes
    try:
        from ..plotting import require_matplotlib
        require_matplotlib("regmech modes plots")
    except RegmechError as exc:          # matplotlib missing
        print(f"no plots: {exc}")
        return
    if result.all_rigid:
        print("no mode-shape plot: every mode is a rigid-body mode at this operating point")
    else:
        plot_mode_shapes(result, path=out / "mode_shapes.png")
        print(f"plot:   {out / 'mode_shapes.png'}")
    if not lin.all_inputs:
        print("no response plot: the scene has no input source")
        return
    f_el = result.frequencies_hz[~result.rigid]
    # up to twice the 12th elastic frequency: the response of a large model would otherwise span its
    # stiffest link, far above the modes a reader looks at (--fmax sets it)
    top = fmax or (2.0 * np.sort(f_el)[min(f_el.size, 12) - 1] if f_el.size else 10.0)
    freqs = np.linspace(top / 1000.0, top, 800)
    speeds = [f"{name}.{'w' if name + '.w' in lin.outputs() else 'v'}" for name in lin.mass_names][:8]
    try:
        resp = harmonic_response(lin, speeds, freqs, inputs=lin.all_inputs[0])
    except RegmechError as exc:
        print(f"no response plot: {exc}")
        return
    resp.plot(path=out / "response.png")
    print(f"plot:   {out / 'response.png'} (mass speeds per unit amplitude of {lin.all_inputs[0]}"
          + (")" if result.all_rigid else ", natural frequencies marked)"))


def _orders_and_speeds(model, orders, speed):
    """The orders and the speed range [rpm] of the Campbell diagram: from ``--orders``/``--speed``, or for a
    model with an ``Engine`` the four-stroke orders and the speeds of its torque map; (None, None) when the
    model has no engine and no orders were asked for."""
    from ..errors import ParameterError
    engines = [c for c in model.components.values() if type(c).__name__.startswith("Engine")
               or any(k.__name__ == "Engine" for k in type(c).__mro__)]
    if orders is None and not engines:
        return None, None
    try:
        ks = [float(x) for x in orders.split(",")] if orders else [0.5, 1.0, 1.5, 2.0, 3.0, 4.0]
    except ValueError:
        raise ParameterError(f"--orders takes numbers separated by commas, e.g. 1,2,4; got {orders!r}") from None
    if speed:
        try:
            lo, hi = (float(x) for x in speed.split(":"))
        except ValueError:
            raise ParameterError(f"--speed takes LOW:HIGH in rpm, e.g. 800:6000; got {speed!r}") from None
    elif engines:
        w = np.asarray(engines[0].torque_map, float)[:, 0]
        lo, hi = max(float(w.min()), 1.0) * 30 / np.pi, float(w.max()) * 30 / np.pi
    else:
        lo, hi = 500.0, 6000.0
    if not (0 <= lo < hi):
        raise ParameterError(f"--speed: LOW:HIGH with 0 <= LOW < HIGH [rpm]; got {lo:g}:{hi:g}")
    return ks, (lo, hi)


def _campbell(result, model, out: Path, orders, speed) -> None:
    from ..errors import RegmechError
    ks, rng = _orders_and_speeds(model, orders, speed)
    if ks is None:
        return
    if result.all_rigid:
        print("no Campbell diagram: no elastic mode at this operating point")
        return
    diagram = result.campbell(ks, rng)
    diagram.table().to_csv(out / "campbell.csv")
    try:
        diagram.plot(path=out / "campbell.png")
    except RegmechError as exc:          # matplotlib missing
        print(f"no Campbell plot: {exc}")
        return
    print(f"plot:   {out / 'campbell.png'} (orders {', '.join(f'{k:g}' for k in ks)}, {rng[0]:.0f}-{rng[1]:.0f} rpm; "
          f"{len(diagram.crossings)} resonance speeds in {out / 'campbell.csv'})")
