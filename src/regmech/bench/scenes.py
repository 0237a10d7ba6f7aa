"""The benchmark scenes: which library scene, with which parameters, over which
horizon, comparing which signals, against which reference.

A ``BenchScene`` names a builder of ``regmech.library.SCENES`` (a scene that
is not in the library of this checkout is skipped, not an error), its
parameters, ``t_end`` and the output interval ``dt_out`` (the error grid, see
``metrics``), the compared signals (continuous quantities), whether it has
stick/slip (then switch-time errors are reported),
the tolerance ladder of the adaptive solvers and the step ladder of the
fixed-step ones, and optionally the MSL reference file it reproduces.

Reference methods (``reference``): DOP853 at rtol 1e-12 (an explicit
8th-order method; with stick/slip the ODE driver locates each friction event
on its dense output to round-off), cross-checked by IDA at rtol 1e-12. Measured
on First and CoupledClutches against DOP853 at rtol 1e-13: DOP853 at 1e-12 is
within 2e-11 (relative to the signal ranges), IDA at 1e-11 within 2e-8 and
at 1e-12 within 3e-9, so the cross-check difference is dominated by IDA's own
error and is an upper bound of the reference's.
"""

from __future__ import annotations

from dataclasses import dataclass

#: solvers that take a fixed step ``h`` instead of a tolerance (and check their error by a companion run at 2h
#: unless ``tol=None``: the work-precision runs pass None to time the bare method, ``runner.Setting``)
FIXED_STEP = ("euler", "rk4", "abm", "expm")
#: tolerance ladders of the adaptive solvers (rtol; atol = rtol * 1e-2, the solvers' default)
FULL_TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
QUICK_TOLERANCES = (1e-4, 1e-6, 1e-8)

#: (primary, cross-check) reference methods as (solver, options)
DEFAULT_REFERENCE = (("scipy:DOP853", {"rtol": 1e-12, "atol": 1e-14}), ("ida", {"rtol": 1e-12, "atol": 1e-14}))


@dataclass(frozen=True)
class MslReference:
    """An MSL reference file (``<file>`` in ``regmech/data/msl``) and the columns compared:
    ``columns`` maps a regmech signal to the CSV column; ``modes`` the friction devices
    whose ``<name>.mode`` columns give the reference's switch times."""

    file: str
    columns: tuple[tuple[str, str], ...]
    modes: tuple[str, ...] = ()


@dataclass(frozen=True)
class BenchScene:
    key: str                                   # unique name in reports, e.g. "train_100"
    scene: str                                 # builder in regmech.library.SCENES
    params: tuple[tuple[str, object], ...]     # builder keyword arguments (hashable)
    t_end: float
    dt_out: float
    signals: tuple[str, ...]
    title: str
    stick_slip: bool = False
    steps: tuple[float, ...] = ()              # fixed-step ladder (coarse to fine) for euler, rk4, abm, expm
    tolerances: tuple[float, ...] = FULL_TOLERANCES
    solvers: tuple[str, ...] | None = None     # None: every solver; else only these
    msl: MslReference | None = None
    note: str = ""
    reference: tuple = DEFAULT_REFERENCE       # (primary, cross-check) as (solver, options)

    def references(self):
        return self.reference

    @property
    def kwargs(self) -> dict:
        return dict(self.params)

    def available(self) -> bool:
        from regmech.library import SCENES
        return self.scene in SCENES

    def build(self):
        """A fresh model (each solver gets its own, so no compiled cache is shared)."""
        from regmech.library import SCENES
        return SCENES[self.scene](**self.kwargs)

    def signal_names(self) -> tuple[str, ...]:
        return self.signals

    def describe(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params)
        return f"{self.scene}({args}), t_end {self.t_end:g} s, output every {self.dt_out:g} s"


def _train(n: int, solvers=None, note="") -> BenchScene:
    # compared: the locomotive and car m, which the coupler wave (about 18 cars/s) reaches at about 11 s
    # even in the longest trains, so every compared signal moves (a car the wave has not reached has a
    # range of round-off, and an error relative to it would mean nothing)
    m = min(n - 1, 200)
    sig = ("car0.v", f"car{m}.v", "coupler0.f", f"coupler{m - 1}.f", f"car{m}.s")
    return BenchScene(
        key=f"train_{n}", scene="train", params=(("n", n), ("c_r", 0.0)), t_end=20.0, dt_out=0.04, signals=sig,
        title=f"train of {n} cars (couplers c 2e7 N/m, d 5e4 N s/m), 20 s",
        steps=(0.04, 0.02, 0.01, 0.005), solvers=solvers,
        note=("rolling resistance off (c_r = 0) so that the model is linear and `expm` can run; with it on, "
              "expm refuses (RoadLoad is nonlinear). " + note).strip())


def all_scenes() -> list[BenchScene]:
    """Every benchmark scene of the full run (those whose builder exists in this checkout)."""
    scenes = [
        BenchScene(
            key="first", scene="first", params=(), t_end=1.0, dt_out=1e-3,
            signals=("inertia1.w", "inertia2.w", "inertia3.w", "spring.tau"),
            title="MSL First: motor, gear 10, elastic load (smooth, linear)",
            steps=(2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4),
            msl=MslReference("First.csv", (("inertia3.w", "inertia3.w"), ("damper.w_rel", "damper.w_rel")))),
        BenchScene(
            key="coupled_clutches", scene="coupled_clutches", params=(), t_end=1.5, dt_out=1e-3,
            signals=("J1.w", "J2.w", "J3.w", "J4.w"), stick_slip=True,
            title="MSL CoupledClutches: three clutches, stick/slip",
            steps=(1e-3, 5e-4, 2.5e-4, 1.25e-4),
            msl=MslReference("CoupledClutches.csv",
                             (("J1.w", "J1.w"), ("clutch1.w_rel", "clutch1.w_rel"), ("clutch2.w_rel", "clutch2.w_rel"),
                              ("clutch3.w_rel", "clutch3.w_rel")),
                             modes=("clutch1", "clutch2", "clutch3"))),
        BenchScene(
            key="one_way_clutch", scene="one_way_clutch", params=(), t_end=2.0, dt_out=2e-3,
            signals=("inertiaIn.w", "inertiaOut.w"), stick_slip=True,
            title="MSL OneWayClutch: freewheel with engagement pulses",
            steps=(2e-3, 1e-3, 5e-4, 2.5e-4),
            msl=MslReference("OneWayClutch.csv", (("inertiaIn.w", "inertiaIn.w"),
                                                  ("oneWayClutch.w_rel", "oneWayClutch.w_rel")))),
        BenchScene(
            key="vehicle_launch", scene="vehicle_launch", params=(), t_end=3.0, dt_out=5e-3,
            signals=("flywheel.w", "gearbox_out.w", "wheel_left.J.w", "body.v", "driveshaft.tau"),
            stick_slip=True, title="vehicle launch: engine, clutch, gearbox, drive shaft, differential, tyres",
            steps=(5e-3, 2.5e-3, 1.25e-3)),
        BenchScene(
            key="excavator_swing", scene="excavator_swing", params=(), t_end=2.0, dt_out=2e-3,
            signals=("motor_1.w", "motor_2.w", "turntable.w", "backlash_1.tau", "armature.i"), stick_slip=True,
            title="excavator swing (SOURCES 004): two motors, backlash, dry friction",
            steps=(2e-3, 1e-3, 5e-4, 2.5e-4)),
        BenchScene(
            key="gear_shift", scene="gear_shift", params=(), t_end=1.0, dt_out=1e-3,
            signals=("input.w", "ring.w", "output.w", "vehicle.w", "output_shaft.tau"), stick_slip=True,
            title="planetary 1-2 upshift: brake released, clutch applied",
            steps=(1e-3, 5e-4, 2.5e-4)),
        BenchScene(
            key="electric_car", scene="electric_car", params=(), t_end=12.0, dt_out=1e-2,
            signals=("rotor.w", "wheels.w", "body.v", "half_shafts.tau"),
            title="electric car: map-based machine, single-speed reduction, regenerative braking",
            steps=(2e-3, 1e-3, 5e-4)),
        BenchScene(
            key="driver_cycle", scene="driver_cycle", params=(), t_end=21.0, dt_out=1e-2,
            signals=("rotor.w", "body.v", "half_shafts.tau", "driver.I"),
            title="driver following an ECE-15 hill (closed loop: PI pedal, regenerative and friction brake)",
            steps=(2e-3, 1e-3, 5e-4)),
        BenchScene(
            key="six_speed_car", scene="six_speed_car", params=(), t_end=4.0, dt_out=5e-3,
            signals=("flywheel.w", "converter.turbine.w", "gearbox.output.w", "body.v", "propshaft.tau"),
            stick_slip=True, title="6-speed automatic: launch through the torque converter, 1-2 shift",
            steps=(5e-3, 2.5e-3, 1.25e-3)),
        BenchScene(
            key="dct_car", scene="dct_car", params=(), t_end=3.5, dt_out=5e-3,
            signals=("flywheel.w", "dct.shaft1.w", "dct.shaft2.w", "body.v", "propshaft.tau"),
            stick_slip=True, title="dual-clutch car: launch on K1, pre-selected 1-2 handover",
            steps=(5e-3, 2.5e-3, 1.25e-3)),
        _train(10),
        _train(100),
        _train(1000),
        _train(10000, solvers=("ida", "expm", "scipy:RK45", "scipy:Radau"),
               note="At n = 10000 only IDA, expm, scipy RK45 and scipy Radau are run (one run takes 5-60 s on "
                    "this machine; LSODA would form a dense 20000 x 20000 Jacobian)."),
    ]
    return [s for s in scenes if s.available()]


def quick_scenes() -> list[BenchScene]:
    """The ``--quick`` set: the two MSL references and the 10-car train, fewer settings."""
    keep = {"first", "coupled_clutches", "train_10"}
    out = []
    for s in all_scenes():
        if s.key in keep:
            out.append(_quick(s))
    return out


def _quick(s: BenchScene) -> BenchScene:
    from dataclasses import replace
    return replace(s, tolerances=QUICK_TOLERANCES, steps=s.steps[1:3] if len(s.steps) >= 3 else s.steps)


def select(keys=None, quick: bool = False) -> list[BenchScene]:
    """Scenes by key (``None``: the full or quick set); an unknown key raises ``ParameterError``."""
    from regmech.errors import ParameterError
    pool = quick_scenes() if quick else all_scenes()
    if not keys:
        return pool
    everything = {s.key: s for s in all_scenes()}
    if quick:
        everything.update({s.key: _quick(s) for s in everything.values()})
    missing = [k for k in keys if k not in everything]
    if missing:
        raise ParameterError(f"unknown benchmark scene(s) {missing}; choose from {sorted(everything)}")
    return [everything[k] for k in keys]
