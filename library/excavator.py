"""Two-motor swing drive of a mining excavator (EKG-5A), the test case of REFERENCES.md [004].

The upper structure (turntable with boom, handle and dipper) is swung by two DC
motors fed in series from one generator (a generator-motor Ward-Leonard drive).
Each motor drives the slewing ring through its own reduction gear; the paper
lumps every gear into the turntable inertia reflected to the motor side, so the
model is a branched three-mass system::

    armature circuit (one current i_a through both motors)
      |  M_1 = C_1 i_a             |  M_2 = C_2 i_a
    motor_1 (J_M1)              motor_2 (J_M2)
      | backlash_1 || damper_1     | backlash_2 || damper_2
      +----------- turntable (J_2, reflected) -----------+
                        | swing_friction (M_c2, stick/slip)
                      ground

Equations (REFERENCES.md [004], motor side, SI units)::

    T_a i_a' + i_a = (u_a(t) - C_1 w_M1 - C_2 w_M2) / R_a          [A]
    J_Mk w_Mk' = C_k i_a - M_el,k - beta (w_Mk - w_2)               [N m]
    M_el,k = C_s dz(phi_k),  phi_k = phi_Mk - phi_2,
        dz(phi) = 0 for |phi| <= dphi/2, else phi - (dphi/2) sign(phi)
    J_2 w_2' = M_el,1 + M_el,2 + beta (w_M1 + w_M2 - 2 w_2) - M_c2 sign(w_2)

The paper writes the dry friction as ``M_c2 sign(w_2)``; here it is a
``BearingFriction`` with stick/slip (the turntable is *held* at rest until the
shafts' torques exceed the break-away torque ``peak * M_c2``), so no sign
function ever enters the integrator. The armature circuit is the library's
``SeriesDCMotors`` (two DC motors on one current, the current an internal
state; ``L = T_a R_a``); its electrical book (``armature.p_el``,
``armature.p_loss``, ``armature.magnetic``, ``armature.p_mech``) is exported
with the run.

Parameters (the paper's digest gives no numbers; these are chosen for an
EKG-5A-class 5 m^3 shovel and the reasoning is stated so they can be checked):

* motors: two ~100 kW, 440 V, 750 rpm DC motors of the swing drive:
  ``w_nominal = 78.5 rad/s``; nominal armature current ~250 A with an armature
  drop of ~20 V gives ``C_k = (440 - 20)/78.5 = 5.35 V s/rad`` (= N m/A), a
  nominal torque ``C_k * 250 = 1340 N m`` each (100 kW / 78.5 rad/s = 1270 N m);
* motor inertia ``J_M = 2.5 kg m^2`` each (rotor with brake pulley and pinion
  shaft; catalogue rotors of this size are 2-3 kg m^2);
* turntable: the loaded upper structure of a 5 m^3 shovel, ~2e6 kg m^2 about the
  swing axis, through a total reduction of ~1:200 reflects to
  ``J_2 = 2e6 / 200^2 = 50 kg m^2`` at the motor side, ten times both motors;
* shafts: ``C_s = 1500 N m/rad`` per branch at the motor side (``C_s * 200^2 =
  6e7 N m/rad`` per branch at the slewing ring, the order of a gear train with
  its ring mesh of this size); the in-phase mode (motors against turntable) is then
  ``sqrt(C_s (1/J_M + 2/J_2)) / 2 pi = 4.1 Hz`` and the anti-phase mode of the
  two motors ``sqrt(C_s / J_M) / 2 pi = 3.9 Hz``: "a few hertz", as measured on
  swing drives;
* backlash ``dphi = 0.08 rad`` per branch at the motor side (the play of the
  gear train, ~0.4 mrad at the slewing ring, i.e. ~1 mm on a 2.5 m ring radius);
* damping ``beta = 10 N m s/rad`` between each motor and the turntable
  (damping ratio ~0.08 of the shaft modes, typical of gear trains);
* dry friction of the slewing ring ``M_c2 = 400 N m`` at the motor side (~15 %
  of the two motors' nominal torque), break-away ``peak = 1.1`` times that;
* armature circuit (two motor armatures, interpoles and the generator in
  series): ``R_a = 0.2 Ohm``, ``T_a = L_a / R_a = 0.05 s``.

The start of the paper: the generator voltage is ramped over 0.5 s to the value
that holds 10 % of nominal speed against the friction, i.e. the steady state of
the equations above: ``u_a = (C_1 + C_2) w + R_a M_c2 / (C_1 + C_2)``.
Simulate about 3 s. What happens (IDA at default settings, the defaults below):
the motors first cross the play while the turntable is held by friction (the
play closes at 0.086 s), the elastic torques rise until the turntable breaks
away (0.179 s), peak at ~750 N m each during the ramp, oscillate in the shaft
modes and settle at ``M_c2/2 = 200 N m`` each; as the ramp ends the motors
overshoot and the play opens (0.943 s) and closes again (1.071 s); the speed
settles at the 10 % target (7.853 rad/s at 3 s against 7.85). The two
branches are identical, so the anti-phase mode stays unexcited.
"""

from __future__ import annotations

import regmech as rm
from regmech.components import Backlash, BearingFriction, Damper, Inertia, SeriesDCMotors
from regmech.signals import Ramp

#: nominal speed of the swing motors [rad/s] (750 rpm)
W_NOMINAL = 78.5


def excavator_swing(speed_fraction: float = 0.1, ramp_time: float = 0.5, j_motor: float = 2.5,
                    j_turntable: float = 50.0, c_shaft: float = 1500.0, backlash: float = 0.08,
                    beta: float = 10.0, m_c2: float = 400.0, peak: float = 1.1, r_a: float = 0.2,
                    t_a: float = 0.05, c_motor: float = 5.35, w_nominal: float = W_NOMINAL) -> rm.Model:
    """EKG-5A swing drive (REFERENCES.md [004]), started to ``speed_fraction`` of nominal speed.

    Parameters as in the module docstring (all at the motor side, SI): motor
    inertias ``j_motor`` [kg m^2], reflected turntable ``j_turntable`` [kg m^2],
    shaft stiffness ``c_shaft`` [N m/rad] and total ``backlash`` [rad] per branch,
    damping ``beta`` [N m s/rad] between each motor and the turntable, dry friction
    ``m_c2`` [N m] (break-away ``peak * m_c2``), armature ``r_a`` [Ohm], ``t_a`` [s],
    motor constants ``c_motor`` [V s/rad] (both motors), ``w_nominal`` [rad/s].
    The voltage rises linearly over ``ramp_time`` [s] from 0 to the steady-state value
    for ``speed_fraction * w_nominal``. Everything starts at rest with the play centred.
    """
    c_sum = 2.0 * c_motor
    w_target = speed_fraction * w_nominal
    u_target = c_sum * w_target + r_a * m_c2 / c_sum
    m = rm.Model("excavator_swing")
    armature = m.add(SeriesDCMotors("armature", u=Ramp(height=u_target, duration=ramp_time),
                                    R=r_a, L=t_a * r_a, k_1=c_motor, k_2=c_motor))
    turntable = m.add(Inertia("turntable", J=j_turntable, phi0=0.0, w0=0.0))
    friction = m.add(BearingFriction("swing_friction", tau_table=[(0.0, m_c2)], peak=peak))
    m.connect(turntable.flange_b, friction.flange)
    for k in (1, 2):
        motor = m.add(Inertia(f"motor_{k}", J=j_motor, phi0=0.0, w0=0.0))
        shaft = m.add(Backlash(f"backlash_{k}", c=c_shaft, b=backlash))
        damper = m.add(Damper(f"damper_{k}", d=beta))
        m.connect(armature.get_flange(f"flange_{k}"), motor.flange_a)
        # turntable on flange_a, motor on flange_b: phi_rel = phi_Mk - phi_2 is the paper's phi_k,
        # and the elastic torque M_el,k = backlash_k.tau is positive while the motor drives
        for dev in (shaft, damper):
            m.connect(turntable.flange_a, dev.flange_a)
            m.connect(dev.flange_b, motor.flange_b)
    return m


__all__ = ["excavator_swing", "W_NOMINAL"]
