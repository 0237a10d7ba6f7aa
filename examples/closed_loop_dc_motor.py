"""DC motor speed loop: a PI controller acting on the motor's voltage, with causal blocks inside the model.

    python examples/closed_loop_dc_motor.py [--out out]

Plant: a separately excited DC motor (``R`` = 1 Ohm, ``L`` = 1 mH, ``k`` = 0.1 V s/rad) drives an inertia
``J`` = 0.01 kg m^2 against a viscous load ``d`` = 0.001 N m s/rad. A ``SpeedSensor`` reads the inertia's
speed, a ``PI`` block (gain 1 V s/rad, integral time 0.1 s, output limited to +-24 V with anti-windup) sets
the voltage: ``DCMotor(u=pi.y)``. The reference is 100 rad/s, stepped to 110 rad/s at 2.5 s; a load torque of
0.2 N m is applied at 3.5 s.

The run is linearised at 2.4 s (``m.linearize(at=res, t=2.4)``): the closed-loop poles (the electrical one
near -R/L and the mechanical pair the PI places) are printed with their damping and natural frequency, and
the linear model's step response to the reference is compared with the simulation.

Physics to expect: the start saturates the voltage at 24 V (an event of kind "limit"), the speed overshoots a
little and settles on the reference (integral action: no steady error, also under the load torque).
Output: ``out/closed_loop_dc_motor.png`` (speed, voltage, current) and a table of the poles.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

import regmech as rm
from regmech.blocks import PI, SpeedSensor
from regmech.components import DCMotor, Damper, Fixed, Inertia, Torque
from regmech.signals import Step


T_STEP = 2.5        # [s] the reference's step


def build(ref=None, load=None) -> rm.Model:
    m = rm.Model("dc_motor_speed_loop")
    J = m.add(Inertia("J", J=0.01))
    visc, g = m.add(Damper("visc", d=0.001)), m.add(Fixed("g"))
    m.connect(J.flange_b, visc.flange_a)
    m.connect(visc.flange_b, g.flange)
    tl = m.add(Torque("load", tau=Step(-0.2, 3.5) if load is None else load))
    m.connect(tl.flange, J.flange_b)
    ws = m.add(SpeedSensor("ws"))
    m.connect(ws.flange, J.flange_b)
    pi = m.add(PI("pi", u=ws.y, ref=Step(10.0, T_STEP, offset=100.0) if ref is None else ref, k=1.0, T_i=0.1,
                  y_min=-24.0, y_max=24.0))
    mot = m.add(DCMotor("mot", u=pi.y, R=1.0, L=1e-3, k=0.1))
    m.connect(mot.flange, J.flange_a)
    return m


def main(out: Path) -> None:
    m = build()
    res = m.simulate(4.0, dt_out=1e-3)
    print(res.stats)
    for ev in res.events:
        print(" ", ev)
    lin = m.linearize(at=res, t=T_STEP - 0.1, inputs=["pi.ref", "load.tau"], outputs=["J.w", "pi.y"])
    print(f"\nlinearised at t = {T_STEP - 0.1:g} s: states {lin.states}")
    print(f"{'pole [1/s]':>28s} {'damping':>9s} {'f_n [Hz]':>9s}")
    for p, z, wn in zip(lin.poles(), lin.damping(), lin.natural_frequencies()):
        print(f"{p.real:14.6g} {p.imag:+13.6g}j {z:9.4f} {wn / (2 * np.pi):9.4g}")
    # the linear model's step response to the reference against the run from the step on
    import scipy.signal
    after = res.t > T_STEP                  # (the row at the step itself is there twice: before and after it)
    tt = np.r_[0.0, res.t[after] - T_STEP]
    keep = tt < 1.0
    _, y, _ = scipy.signal.lsim(lin.to_scipy(), np.c_[np.full(keep.sum(), 10.0), np.zeros(keep.sum())],
                                tt[keep])
    w_lin = res.at("J.w", T_STEP) + y[:, 0]
    w_run = np.r_[res.at("J.w", T_STEP), res["J.w"][after]][keep]
    print(f"largest difference run - linear model over 1 s after the step: "
          f"{np.max(np.abs(w_run - w_lin)):.3g} rad/s (the step: 10 rad/s)")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no figure")
        return
    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(3, 1, sharex=True, figsize=(7, 7))
    ax[0].plot(res.t, res["J.w"], label="run")
    ax[0].plot(tt[keep] + T_STEP, w_lin, "--", label=f"linear model (step at {T_STEP:g} s)")
    ax[0].set_ylabel("speed [rad/s]")
    ax[0].legend()
    ax[1].plot(res.t, res["pi.y"])
    ax[1].set_ylabel("voltage [V]")
    ax[2].plot(res.t, res["mot.i"])
    ax[2].set_ylabel("current [A]")
    ax[2].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(out / "closed_loop_dc_motor.png", dpi=120)
    print(f"figure: {out / 'closed_loop_dc_motor.png'}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(os.environ.get("REGMECH_EXAMPLES_OUT", "out")),
                        help="folder for the figure")
    main(parser.parse_args().out)
