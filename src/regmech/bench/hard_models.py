"""Models of the hard cases and their analytic (or independent) answers.

Each builder returns a regmech model; each ``*_answer`` function returns
what the model must do, from a closed form or from ``linear_ref`` (exact
response of a linear chain from hand-assembled matrices). Units SI.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

import regmech as rm
from regmech.components import (Clutch, Damper, Fixed, Force, FrictionContact, IdealGear, Inertia, LinearSpeed, Mass,
                                Spring, Torque)
from regmech.signals import Pulse, Ramp, Step

from .linear_ref import LinearChain

G = 9.80665


# ----------------------------------------------------------------------------- stretched spectra
def benchmark_chain(n: int, tau=None, c: float = 1e4, d: float = 1.0) -> rm.Model:
    """The benchmark chain: ``n`` inertias ``J_i = 1 + 0.01 (i mod 7)`` kg m^2 joined by spring-dampers
    (``c`` [N m/rad], ``d`` [N m s/rad]), driven at the first by a torque ``tau`` (default a 10 N m sine at
    5 Hz), the last held to the ground by a 1e3 N m/rad spring; starting at rest. Shared by
    ``benchmarks/bench_foundation.py``, the peers benchmark and the tests of the fast paths."""
    from regmech.components import SpringDamper, Torque
    from regmech.signals import Sine
    m = rm.Model(f"chain{n}")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=Sine(amplitude=10.0, freq_hz=5.0) if tau is None else tau))
    J = [m.add(Inertia(f"J{i}", J=1.0 + 0.01 * (i % 7), phi0=0.0, w0=0.0)) for i in range(n)]
    m.connect(drive.flange, J[0].flange_a)
    for i in range(n - 1):
        sd = m.add(SpringDamper(f"sd{i}", c=c, d=d))
        m.connect(J[i].flange_b, sd.flange_a)
        m.connect(sd.flange_b, J[i + 1].flange_a)
    end = m.add(Spring("ground_spring", c=1e3))
    m.connect(J[-1].flange_b, end.flange_a)
    m.connect(end.flange_b, fixed.flange)
    return m


def stretched_chain(ratio: float, n: int = 6, zeta: float = 0.05, torque: float = 1.0, t_ramp: float = 2.0):
    """Fixed-free torsional chain of n unit inertias whose link stiffnesses grow geometrically,
    ``c_k = q^k`` (k = 0 the link to the ground), with q chosen so that the highest over the
    lowest natural frequency is exactly ``ratio``; each link has a damper ``2 zeta sqrt(c_k)``
    (about ``zeta`` damping per local mode). A torque ramps to ``torque`` over ``t_ramp`` on the
    free end (the softest part is next to the ground, the stiffest at the free end)."""
    def chain_of(q):
        links = [(0, None, 1.0, 2 * zeta)] + [(k, k - 1, q ** k, 2 * zeta * math.sqrt(q ** k)) for k in range(1, n)]
        return LinearChain(f"stretched_{ratio:.0e}", [1.0] * n, links, n - 1,
                           [(0.0, 0.0, torque / t_ramp), (t_ramp, torque, 0.0)], names=[f"J{k}" for k in range(n)])

    def log_ratio_error(log_q):
        w = chain_of(math.exp(log_q)).frequencies()
        return math.log(w[-1] / w[0]) - math.log(ratio)

    # omega_max / omega_min grows about like q^((n-1)/2): bracket the root around that
    log_q = brentq(log_ratio_error, 1e-3, 4.0 * math.log(ratio) / (n - 1) + 1.0, xtol=1e-14)
    return chain_of(math.exp(log_q)), Ramp(height=torque, duration=t_ramp)


def near_rigid_chain(n: int = 8, c: float = 1e3, stiff_factor: float = 1e6, zeta: float = 0.02):
    """Fixed-free chain of n unit inertias, links ``c`` with dampers ``2 zeta sqrt(c)``; the link
    between the middle masses is ``stiff_factor`` times stiffer (a near-rigid shaft). A torque
    ramps to 10 N m over 0.5 s at the free end."""
    links = []
    for k in range(n):
        ck = c * (stiff_factor if k == n // 2 else 1.0)
        links.append((k, None if k == 0 else k - 1, ck, 2 * zeta * math.sqrt(ck)))
    chain = LinearChain("near_rigid_shaft", [1.0] * n, links, n - 1, [(0.0, 0.0, 20.0), (0.5, 10.0, 0.0)],
                        names=[f"J{k}" for k in range(n)])
    return chain, Ramp(height=10.0, duration=0.5)


# ----------------------------------------------------------------------------- extreme parameters
def inertia_ratio_chain():
    """A flywheel J = 1e4 kg m^2 on a spring-damper to the ground (c 100, d 10) and a small
    inertia J = 1e-4 kg m^2 (ratio 1e8) on an elastic shaft to it (c 1e3, d 0.05); a torque
    ramps to 1 N m over 1 s on the small inertia."""
    chain = LinearChain("inertia_ratio_1e8", [1e4, 1e-4], [(0, None, 100.0, 10.0), (1, 0, 1e3, 0.05)], 1,
                        [(0.0, 0.0, 1.0), (1.0, 1.0, 0.0)], names=["flywheel", "small"])
    return chain, Ramp(height=1.0, duration=1.0)


def tiny_mass_chain():
    """Two 10 t masses joined through a 1 g mass (mass ratio 1e7) by two couplings (k 1e5 N/m,
    d 10 N s/m each); a force ramps to 1e4 N over 1 s on the first heavy mass. Free-free: the
    pair drifts away while the tiny mass rides between them."""
    chain = LinearChain("tiny_mass", [1e4, 1e-3, 1e4], [(1, 0, 1e5, 10.0), (2, 1, 1e5, 10.0)], 0,
                        [(0.0, 0.0, 1e4), (1.0, 1e4, 0.0)], translational=True, names=["heavy_a", "tiny", "heavy_b"])
    return chain, Ramp(height=1e4, duration=1.0)


def gear_1_1000(ratio: float = 1000.0, j_motor: float = 1e-3, j_load: float = 1e3, f_hz: float = 0.5,
                torque: float = 0.01):
    """Motor (J ``j_motor``) driven by a constant ``torque`` -> ideal gear ``ratio`` (1:1000) ->
    load (J ``j_load``) on a spring to the ground tuned to ``f_hz``. With the reflected inertia
    ``J = j_load + ratio^2 j_motor`` and ``c = J (2 pi f)^2``:
    ``phi_load(t) = (ratio torque / c)(1 - cos(2 pi f t))``, ``w_motor = ratio w_load``."""
    m = rm.Model("gear_1_1000")
    fixed = m.add(Fixed("fixed"))
    drive = m.add(Torque("drive", tau=torque))
    motor = m.add(Inertia("motor", J=j_motor, phi0=0.0, w0=0.0))
    gear = m.add(IdealGear("gear", ratio=ratio))
    load = m.add(Inertia("load", J=j_load))
    j_total = j_load + ratio ** 2 * j_motor
    c = j_total * (2 * math.pi * f_hz) ** 2
    spring = m.add(Spring("spring", c=c))
    m.connect(drive.support, fixed.flange)
    m.connect(drive.flange, motor.flange_a)
    m.connect(motor.flange_b, gear.flange_a)
    m.connect(gear.support, fixed.flange)
    m.connect(gear.flange_b, load.flange_a)
    m.connect(load.flange_b, spring.flange_a)
    m.connect(spring.flange_b, fixed.flange)
    om = 2 * math.pi * f_hz

    def answer(t):
        phi = ratio * torque / c * (1 - np.cos(om * t))
        w = ratio * torque / c * om * np.sin(om * t)
        return {"load.phi": phi, "load.w": w, "motor.w": ratio * w, "motor.phi": ratio * phi}
    return m, answer


# ----------------------------------------------------------------------------- stick/slip
def belt_oscillator(m=1.0, k=100.0, mu=0.3, peak=1.5, fn=10.0, v_belt=0.2):
    """Block on a moving belt, tied to a wall by a spring (the classic stick-slip oscillator):
    the block sticks to the belt until the spring force exceeds the static friction
    ``peak mu fn``, slips back under the kinetic friction ``mu fn``, and sticks again."""
    mod = rm.Model("belt")
    wall = mod.add(Fixed("wall", domain="translational"))
    belt = mod.add(LinearSpeed("belt", v_ref=v_belt))
    block = mod.add(Mass("block", m=m, s0=0.0, v0=v_belt))
    spring = mod.add(Spring("spring", c=k, domain="translational"))
    contact = mod.add(FrictionContact("contact", mu=mu, peak=peak, fn=fn))
    mod.connect(wall.flange, spring.flange_a)
    mod.connect(spring.flange_b, block.flange_a)
    mod.connect(block.flange_b, contact.flange_a)
    mod.connect(contact.flange_b, belt.flange)
    return mod


def belt_answer(m=1.0, k=100.0, mu=0.3, peak=1.5, fn=10.0, v_belt=0.2):
    """First stick duration, then the limit cycle's slip and stick durations [s] (closed form:
    harmonic slip phase about the kinetic equilibrium ``x_k = mu fn / k`` from the break-away
    point ``x_b = peak mu fn / k`` with the belt's speed, until the speed again equals the belt's)."""
    fk, fs = mu * fn, peak * mu * fn
    om = math.sqrt(k / m)
    xk, xb = fk / k, fs / k
    delta = xb - xk
    alpha = math.atan2(om * delta, v_belt)
    slip = (2 * math.pi - 2 * alpha) / om
    x_end = xk + delta * math.cos(2 * alpha) - v_belt / om * math.sin(2 * alpha)
    stick = (xb - x_end) / v_belt
    return xb / v_belt, slip, stick


def simultaneous_lock(w0: float = 10.0):
    """A hub (J 14/3) and three satellites (J 1, 2, 4, all at ``w0``) joined to it by clutches with
    kinetic torques 2, 4, 8 N m: every satellite decelerates at 2 rad/s^2 and the hub
    accelerates at 3 rad/s^2, so all three clutches reach zero slip together at
    ``t = w0 / 5`` (10 -> 2 s), and everything then turns at the momentum-conserving
    ``w = 70 / (7 + 14/3) = 6`` rad/s. The satellites differ, so the three zeros coincide only
    to round-off."""
    m = rm.Model("simultaneous_lock")
    hub = m.add(Inertia("hub", J=14.0 / 3.0, phi0=0.0, w0=0.0))
    for k, J in enumerate((1.0, 2.0, 4.0), start=1):
        sat = m.add(Inertia(f"sat{k}", J=J, phi0=0.0, w0=w0))
        cl = m.add(Clutch(f"clutch{k}", mu=0.5, peak=1.2, cgeo=1.0, fn_max=4.0 * J))    # kinetic 2 J N m
        m.connect(sat.flange_b, cl.flange_a)
        m.connect(cl.flange_b, hub.flange_a if k % 2 else hub.flange_b)
    return m


def zero_speed_engagement():
    """J1 (1 kg m^2, from rest, 1 N m) and J2 (1 kg m^2, from 0.25 rad/s, 0.5 N m) reach the same
    speed 0.5 rad/s at t = 0.5 s, exactly when the clutch between them engages (normal force
    steps to 10 N). It must lock at once (Free -> Stuck, no slip) and stay locked: the pair then
    accelerates at 0.75 rad/s^2 and the clutch holds 0.25 N m, far below its capacity 5 N m."""
    m = rm.Model("zero_speed_engagement")
    d1 = m.add(Torque("drive1", tau=1.0))
    j1 = m.add(Inertia("J1", J=1.0, phi0=0.0, w0=0.0))
    cl = m.add(Clutch("clutch", mu=0.5, peak=1.1, fn_max=10.0, f_normalized=Step(start_time=0.5)))
    j2 = m.add(Inertia("J2", J=1.0, phi0=0.0, w0=0.25))
    d2 = m.add(Torque("drive2", tau=0.5))
    m.connect(d1.flange, j1.flange_a)
    m.connect(j1.flange_b, cl.flange_a)
    m.connect(cl.flange_b, j2.flange_a)
    m.connect(d2.flange, j2.flange_b)

    def answer(t):
        t = np.asarray(t, float)
        locked = t >= 0.5
        w1 = np.where(locked, 0.5 + 0.75 * (t - 0.5), t)
        w2 = np.where(locked, 0.5 + 0.75 * (t - 0.5), 0.25 + 0.5 * t)
        return {"J1.w": w1, "J2.w": w2}
    return m, answer


def slope_hold(m_veh: float = 1200.0, slope_deg: float = 15.0, mu: float = 0.8, peak: float = 1.2,
               t_hold: float = 100.0, pull_rate: float = 2000.0):
    """A vehicle (mass ``m_veh``) parked on a slope, its brake a ``FrictionContact`` to the ground
    with the normal force ``m g cos(theta)``; gravity along the slope is a constant ``Force``
    ``-m g sin(theta)``. It must stay put, without drift, until ``t_hold``; from then a winch
    pulls down the slope with a force rising at ``pull_rate`` [N/s], and the brake breaks away
    when the total exceeds ``peak mu m g cos(theta)``, at
    ``t_b = t_hold + (peak mu fn - m g sin(theta)) / pull_rate``. Sliding (Backward), the kinetic
    friction ``mu fn`` opposes the motion:
    ``m v(t) = (mu fn - m g sin) (t - t_b) - pull_rate ((t - t_hold)^2 - (t_b - t_hold)^2) / 2``."""
    th = math.radians(slope_deg)
    fn = m_veh * G * math.cos(th)
    f_slope = m_veh * G * math.sin(th)
    mod = rm.Model("slope_hold")
    ground = mod.add(Fixed("ground", domain="translational"))
    body = mod.add(Mass("vehicle", m=m_veh, s0=0.0, v0=0.0))
    gravity = mod.add(Force("gravity", f=-f_slope))
    winch = mod.add(Force("winch", f=Ramp(height=-pull_rate * 1e3, duration=1e3, start_time=t_hold)))
    brake = mod.add(FrictionContact("brake", mu=mu, peak=peak, fn=fn))
    for src in (gravity, winch):
        mod.connect(src.flange, body.flange_a)
        mod.connect(src.support, ground.flange)
    mod.connect(body.flange_b, brake.flange_a)
    mod.connect(brake.flange_b, ground.flange)
    t_b = t_hold + (peak * mu * fn - f_slope) / pull_rate

    def answer(t):
        t = np.asarray(t, float)
        tau = np.clip(t - t_b, 0.0, None)
        v = ((mu * fn - f_slope) * tau - pull_rate * ((t - t_hold) ** 2 - (t_b - t_hold) ** 2) / 2) / m_veh
        s = ((mu * fn - f_slope) * tau ** 2 / 2
             - pull_rate * ((t - t_hold) ** 3 / 3 - (t_b - t_hold) ** 3 / 3 - (t_b - t_hold) ** 2 * tau) / 2) / m_veh
        return {"vehicle.v": np.where(t > t_b, v, 0.0), "vehicle.s": np.where(t > t_b, s, 0.0)}
    return mod, t_b, answer


# ----------------------------------------------------------------------------- long horizon
def undamped_chain(n: int = 4, c: float = 100.0, J: float = 1.0, phi0: float = 0.1):
    """Fixed-free chain of n inertias and n springs, no damping, released from rest with the
    first inertia turned by ``phi0``: the energy ``sum J w^2/2 + sum c e^2/2`` stays ``c phi0^2``
    (two springs stretched by phi0) for ever."""
    m = rm.Model("undamped_chain")
    fixed = m.add(Fixed("fixed"))
    prev = fixed.flange
    for k in range(n):
        jk = m.add(Inertia(f"J{k}", J=J, phi0=phi0 if k == 0 else 0.0, w0=0.0))
        sp = m.add(Spring(f"spring{k}", c=c))
        m.connect(prev, sp.flange_a)
        m.connect(sp.flange_b, jk.flange_a)
        prev = jk.flange_b
    return m, c * phi0 ** 2


def energy(res, n: int) -> np.ndarray:
    return sum(res[f"J{k}.kinetic"] for k in range(n)) + sum(res[f"spring{k}.potential"] for k in range(n))


# ----------------------------------------------------------------------------- discontinuous inputs
def damped_inertia(*torques, J: float = 2.0, d: float = 4.0, name="torque_steps"):
    """An inertia J on a damper d to the ground, driven by the sum of the given torque signals."""
    m = rm.Model(name)
    fixed = m.add(Fixed("fixed"))
    body = m.add(Inertia("J", J=J, phi0=0.0, w0=0.0))
    damper = m.add(Damper("damper", d=d))
    m.connect(body.flange_b, damper.flange_a)
    m.connect(damper.flange_b, fixed.flange)
    for k, sig in enumerate(torques):
        src = m.add(Torque(f"drive{k}", tau=sig))
        m.connect(src.flange, body.flange_a)
    return m


def piecewise_constant_answer(levels, J, d, t):
    """``J w' + d w = T(t)`` from rest, T piecewise constant: ``levels`` = [(t_k, T_k)] ascending
    (T = T_k from t_k on, 0 before the first). Exact ``w`` and ``phi`` at the times ``t``:
    on each piece ``w = T/d + (w_k - T/d) e^{-a (t - t_k)}``, ``a = d/J``, and ``phi`` its integral."""
    t = np.asarray(t, float)
    pieces = list(levels)
    if not pieces or pieces[0][0] > 0:
        pieces.insert(0, (0.0, 0.0))
    a = d / J
    w = np.zeros_like(t)
    phi = np.zeros_like(t)
    w_k = phi_k = 0.0
    for idx, (start, T) in enumerate(pieces):
        end = pieces[idx + 1][0] if idx + 1 < len(pieces) else math.inf
        w_inf = T / d

        def flow(dt):
            return (w_inf + (w_k - w_inf) * np.exp(-a * dt),
                    phi_k + w_inf * dt + (w_k - w_inf) / a * (1 - np.exp(-a * dt)))
        sel = (t >= start) & (t < end)
        w[sel], phi[sel] = flow(t[sel] - start)
        if math.isfinite(end):
            w_k, phi_k = (float(v) for v in flow(end - start))
    return w, phi


def pulse_levels(p: Pulse, t_end: float):
    """[(t_k, value from t_k on)] of a Pulse up to t_end (the value is read just after each
    breakpoint: at a breakpoint itself the phase is subject to round-off)."""
    pts = [0.0] + [b for b in p.breakpoints(0.0, t_end) if b > 0]
    return [(b, p.value(b + 1e-6 * p.period)) for b in pts]


__all__ = ["stretched_chain", "near_rigid_chain", "inertia_ratio_chain", "tiny_mass_chain", "gear_1_1000",
           "belt_oscillator", "belt_answer", "simultaneous_lock", "zero_speed_engagement", "slope_hold",
           "undamped_chain", "energy", "damped_inertia", "piecewise_constant_answer", "pulse_levels"]


# ----------------------------------------------------------------------------- wide coupling
def satellite_hub(n: int) -> rm.Model:
    """A hub inertia (1 kg m^2) joined to n satellite inertias (0.1-0.7 kg m^2) by spring-dampers
    (1e3-5e3 N m/rad, 1 N m s/rad), each satellite damped to ground (0.5 N m s/rad); a torque step of
    10 N m on the hub at 0.1 s. Every satellite row couples to the hub, so no ordering of the unknowns
    gives a narrow band: the case for IDA's dense and sparse linear solvers (``choose_linsolver``)."""
    from regmech.components import SpringDamper
    m = rm.Model(f"hub_{n}")
    h = m.add(Inertia("hub", J=1.0))
    g = m.add(Fixed("ground"))
    tq = m.add(Torque("drive", tau=Step(height=10.0, start_time=0.1)))
    m.connect(tq.flange, h.flange_a)
    for i in range(n):
        s = m.add(Inertia(f"sat{i}", J=0.1 * (1 + i % 7)))
        k = m.add(SpringDamper(f"link{i}", c=1e3 * (1 + i % 5), d=1.0))
        d = m.add(Damper(f"drag{i}", d=0.5))
        m.connect(h.flange_b, k.flange_a)
        m.connect(k.flange_b, s.flange_a)
        m.connect(s.flange_b, d.flange_a)
        m.connect(d.flange_b, g.flange)
    return m
