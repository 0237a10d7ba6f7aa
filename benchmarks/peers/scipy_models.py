"""Hand-written scipy models: what a competent user would write instead of regmech.

Each model is the reduced ODE of the regmech scene written out by hand and
integrated by ``scipy.integrate.solve_ivp`` with ``t_eval`` on the output grid.
A run returns ``(outputs, info)``: ``outputs`` maps a regmech signal name to
its values on the grid, ``info`` holds ``nfev`` (right-hand-side calls) and,
for the hybrid model, ``segments`` (solve_ivp calls), ``events`` and
``switches`` (time and clutch number of each state event).

Models (parameters and signs as in ``regmech.library`` and MSL):

* ``first``: MSL Rotational.Examples.First. The ideal gear (ratio r = 10)
  makes inertia1 (J1 = 0.1 kg m^2) ride on inertia2 (J2 = 2 kg m^2):
  ``w1 = r w2``, so the lumped inertia is ``Je = J2 + r^2 J1`` [kg m^2] driven
  by ``r tau(t)``, ``tau = 10 sin(2 pi 5 t)`` [N m]. States
  ``(phi2, w2, phi3, w3)`` [rad, rad/s]::

      Je w2' = r tau(t) + c (phi3 - phi2) - d w2      (c = 1e4 N m/rad, d = 10 N m s/rad)
      J3 w3' = -c (phi3 - phi2)                       (J3 = 2 kg m^2)

  all starting at 0.

* ``coupled_clutches``: MSL Rotational.Examples.CoupledClutches, four unit
  inertias ``J1..J4`` in a row joined by clutches ``k = 1, 2, 3`` (between
  ``J_k`` and ``J_k+1``, relative speed ``w_rel,k = w_k+1 - w_k``), J1 driven
  by ``10 sin(2 pi 5 t)`` and starting at 10 rad/s. Clutch k presses with
  ``fn_k = 20 f_k(t)`` [N] (``f_1 = cos(2 pi 0.2 t)``, ``f_2`` a unit step at
  0.4 s, ``f_3`` at 0.9 s); ``fn_k <= 0``: free (no torque). Sliding: the
  clutch torque ``T_k = mu fn_k sign(w_rel,k)`` (mu = 0.5) speeds up ``J_k``
  and slows ``J_k+1``. Stuck: ``w_rel,k`` stays 0 and the holding torque
  ``T_k`` follows from the lumped group; it breaks away when
  ``|T_k| > peak mu fn_k`` (peak = 1.1) in the direction of ``T_k``.
  Integrated piecewise: the signal breakpoints (0.4, 0.9 s and 1.25 s, where
  ``f_1`` turns negative) end a segment, and so does a terminal event (a
  sliding clutch's relative speed through zero, a stuck clutch's holding
  torque through its capacity); at each restart the modes are chosen anew
  (stick where the holding torque fits the capacity, else slide in its
  direction) and ``solve_ivp`` starts again from the event state.

* ``chain``: the benchmark chain of ``benchmarks/bench_foundation.py``: n
  inertias ``J_i = 1 + 0.01 (i mod 7)`` joined by spring-dampers
  (c = 1e4 N m/rad, d = 1 N m s/rad), ``J_0`` driven by ``10 sin(2 pi 5 t)``,
  ``J_n-1`` grounded through a spring (1e3 N m/rad), all at rest at 0.
  Vectorised numpy right-hand side on ``(phi_0..phi_n-1, w_0..w_n-1)``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

TWO_PI = 2.0 * math.pi
#: output interval of the benchmark runs [s] per model
DT_OUT = {"first": 1e-3, "coupled_clutches": 1e-3, "chain": 1e-2}
T_END = {"first": 1.0, "coupled_clutches": 1.5, "chain": 1.0}


def grid(t_end: float, dt_out: float) -> np.ndarray:
    """The output instants 0, dt_out, ..., t_end (as regmech's output grid)."""
    return np.linspace(0.0, t_end, int(round(t_end / dt_out)) + 1)


# --------------------------------------------------------------------------- First
FIRST = dict(amp=10.0, freq=5.0, j1=0.1, j2=2.0, j3=2.0, ratio=10.0, c=1e4, d=10.0)
FIRST_SIGNALS = ("inertia1.w", "inertia2.w", "inertia3.w")


def first(method: str = "DOP853", rtol: float = 1e-6, atol: float | None = None,
          t_end: float = 1.0, dt_out: float = 1e-3):
    """MSL First by hand (see the module docstring); outputs the three inertias' speeds [rad/s]."""
    p = FIRST
    amp, om, r, c, d, j3 = p["amp"], TWO_PI * p["freq"], p["ratio"], p["c"], p["d"], p["j3"]
    je = p["j2"] + r * r * p["j1"]

    def rhs(t, y):
        phi2, w2, phi3, w3 = y
        s = c * (phi3 - phi2)
        return [w2, (r * amp * math.sin(om * t) + s - d * w2) / je, w3, -s / j3]

    tg = grid(t_end, dt_out)
    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0, 0.0, 0.0], method=method, t_eval=tg, rtol=rtol,
                    atol=rtol * 1e-2 if atol is None else atol)
    if not sol.success:
        raise RuntimeError(f"hand First ({method}): {sol.message}")
    w2, w3 = sol.y[1], sol.y[3]
    return {"inertia1.w": r * w2, "inertia2.w": w2, "inertia3.w": w3, "damper.w_rel": -w2}, {"nfev": sol.nfev}


# --------------------------------------------------------------------------- CoupledClutches
CC = dict(amp=10.0, freq=5.0, w0=10.0, fn_max=20.0, mu=0.5, peak=1.1, f1_hz=0.2, t2=0.4, t3=0.9)
CC_SIGNALS = ("J1.w", "J2.w", "J3.w", "J4.w")
FREE, STUCK = None, 0          # modes: None free, 0 stuck, +1 forward (w_rel > 0), -1 backward


def _cc_fn(t: float) -> tuple[float, float, float]:
    """Normal forces [N] of the three clutches at t (0 where disengaged)."""
    p = CC
    f1 = math.cos(TWO_PI * p["f1_hz"] * t)
    f = (f1, 1.0 if t >= p["t2"] else 0.0, 1.0 if t >= p["t3"] else 0.0)
    return tuple(p["fn_max"] * x if x > 0.0 else 0.0 for x in f)


def _cc_accelerations(t, w, modes, J):
    """Accelerations of J1..J4 and holding torques of the stuck clutches for the given modes.

    Inertias joined by stuck clutches form groups with one acceleration
    ``a_g = sum(tau_i) / sum(J_i)`` over the group; a stuck clutch k holds
    ``T_k = sum over the group's inertias left of it of (J_i a_g - tau_i)``.
    """
    p = CC
    fn = _cc_fn(t)
    tau = [p["amp"] * math.sin(TWO_PI * p["freq"] * t), 0.0, 0.0, 0.0]
    for k, m in enumerate(modes):
        if m:                          # sliding (+1 / -1): kinetic torque mu fn sign(w_rel)
            T = m * p["mu"] * fn[k]
            tau[k] += T
            tau[k + 1] -= T
    a = [0.0] * 4
    hold = [0.0] * 3
    i = 0
    while i < 4:                       # groups of inertias joined by stuck clutches
        j = i
        while j < 3 and modes[j] == STUCK:
            j += 1
        jt = sum(J[i:j + 1])
        ag = sum(tau[i:j + 1]) / jt
        left = 0.0
        for q in range(i, j + 1):
            a[q] = ag
            if q < j:
                left += J[q] * ag - tau[q]
                hold[q] = left
        i = j + 1
    return a, hold, fn


def _cc_choose_modes(t, w, candidates, forced, J):
    """Modes after a restart: free where fn <= 0; stuck for the candidates (clutches at zero relative
    speed) whose holding torque fits ``peak mu fn``, else sliding in the direction of the torque (the worst
    excess is released first, then the others are judged again); sliding by the sign of w_rel otherwise.
    ``forced`` maps a clutch that just broke away to its sliding direction."""
    p = CC
    fn = _cc_fn(t)
    modes = []
    for k in range(3):
        if fn[k] <= 0.0:
            modes.append(FREE)
        elif k in forced:
            modes.append(forced[k])
        elif k in candidates:
            modes.append(STUCK)
        else:
            modes.append(1 if w[k + 1] - w[k] > 0.0 else -1)
    for _ in range(4):                 # at most one release per clutch
        _, hold, _ = _cc_accelerations(t, w, modes, J)
        worst, excess = None, 1.0
        for k in range(3):
            if modes[k] == STUCK:
                cap = p["peak"] * p["mu"] * fn[k]
                if abs(hold[k]) > cap * excess:
                    worst, excess = k, abs(hold[k]) / cap
        if worst is None:
            return modes
        modes[worst] = 1 if hold[worst] > 0.0 else -1
    return modes


def coupled_clutches(method: str = "DOP853", rtol: float = 1e-6, atol: float | None = None,
                     t_end: float = 1.5, dt_out: float = 1e-3, max_segments: int = 1000):
    """MSL CoupledClutches by hand with event restarts (see the module docstring)."""
    p = CC
    J = (1.0, 1.0, 1.0, 1.0)
    atol = rtol * 1e-2 if atol is None else atol
    tg = grid(t_end, dt_out)
    breaks = [b for b in (p["t2"], p["t3"], math.acos(0.0) / (TWO_PI * p["f1_hz"])) if 0.0 < b < t_end] + [t_end]
    breaks.sort()
    t0, w = 0.0, np.array([p["w0"], 0.0, 0.0, 0.0])
    modes = _cc_choose_modes(t0, w, set(), {}, J)
    out_t, out_y = [tg[:1]], [w[:, None].copy()]
    nfev = segments = events = 0
    switches = []                      # (t, clutch number 1..3) of every state event
    bi = 0
    while t0 < t_end:
        if segments >= max_segments:
            raise RuntimeError(f"hand CoupledClutches: more than {max_segments} segments by t = {t0}")
        while breaks[bi] <= t0:
            bi += 1
        t1 = breaks[bi]
        m = tuple(modes)

        def rhs(t, y, m=m):
            return _cc_accelerations(t, y, m, J)[0]

        evs, ev_clutch = [], []
        for k, mk in enumerate(m):
            if mk in (1, -1):          # a sliding clutch: its relative speed through zero
                def g(t, y, k=k):
                    return y[k + 1] - y[k]
                g.terminal, g.direction = True, -mk
                evs.append(g)
                ev_clutch.append((k, "zero"))
            elif mk == STUCK:          # a stuck clutch: holding torque through +- peak mu fn
                for sgn in (1, -1):
                    def g(t, y, k=k, sgn=sgn):
                        a, hold, fn = _cc_accelerations(t, y, m, J)
                        return hold[k] - sgn * p["peak"] * p["mu"] * fn[k]
                    g.terminal, g.direction = True, sgn
                    evs.append(g)
                    ev_clutch.append((k, sgn))
        sel = (tg > t0) & (tg <= t1)
        t_eval = tg[sel]
        extra = not (t_eval.size and t_eval[-1] == t1)      # the segment's end state is needed for the restart
        if extra:
            t_eval = np.append(t_eval, t1)
        sol = solve_ivp(rhs, (t0, t1), w, method=method, t_eval=t_eval, rtol=rtol, atol=atol,
                        events=evs or None)
        if sol.status < 0:
            raise RuntimeError(f"hand CoupledClutches ({method}) at t = {t0}: {sol.message}")
        nfev += sol.nfev
        segments += 1
        candidates = {q for q in range(3) if m[q] == STUCK}
        if sol.status == 1:            # a terminal event: restart from the event state in the new mode
            keep = sol.t.size
            hit = next(i for i, te in enumerate(sol.t_events) if len(te))
            t0, w = float(sol.t_events[hit][0]), sol.y_events[hit][0].copy()
            events += 1
            k, kind = ev_clutch[hit]
            switches.append((t0, k + 1))
            forced = {}
            if kind == "zero":
                candidates.add(k)
            else:
                candidates.discard(k)
                forced[k] = kind       # broke away: slides in the direction of the holding torque
        else:                          # a breakpoint of the normal forces: modes anew
            keep = sol.t.size - 1 if extra else sol.t.size
            t0, w, forced = t1, sol.y[:, -1].copy(), {}
        out_t.append(sol.t[:keep])
        out_y.append(sol.y[:, :keep])
        modes = _cc_choose_modes(t0, w, candidates, forced, J)
    y = np.concatenate(out_y, axis=1)
    t = np.concatenate(out_t)
    if t.size != tg.size:
        raise RuntimeError(f"hand CoupledClutches: {t.size} output points instead of {tg.size}")
    return ({name: y[i] for i, name in enumerate(CC_SIGNALS)},
            {"nfev": nfev, "segments": segments, "events": events, "switches": switches})


# --------------------------------------------------------------------------- chain
CHAIN = dict(amp=10.0, freq=5.0, c=1e4, d=1.0, c_ground=1e3)


def chain_inertias(n: int) -> np.ndarray:
    return 1.0 + 0.01 * (np.arange(n) % 7)


def chain_signals(n: int) -> tuple[str, ...]:
    """Compared signals: the speeds of the first, middle and last inertias."""
    return tuple(dict.fromkeys(f"J{i}.w" for i in (0, n // 2, n - 1)))


def chain_rhs(n: int):
    """The chain's right-hand side ``f(t, y)`` on ``y = (phi, w)``, vectorised."""
    p = CHAIN
    inv_j = 1.0 / chain_inertias(n)
    amp, om, c, d, cg = p["amp"], TWO_PI * p["freq"], p["c"], p["d"], p["c_ground"]

    def rhs(t, y):
        phi, w = y[:n], y[n:]
        f = c * (phi[1:] - phi[:-1]) + d * (w[1:] - w[:-1])     # torque of link i on J_i (and -f on J_i+1)
        acc = np.zeros(n)
        acc[:-1] += f
        acc[1:] -= f
        acc[0] += amp * math.sin(om * t)
        acc[-1] -= cg * phi[-1]
        return np.concatenate((w, acc * inv_j))
    return rhs


def chain(n: int, method: str = "DOP853", rtol: float = 1e-6, atol: float | None = None,
          t_end: float = 1.0, dt_out: float = 1e-2):
    """The benchmark chain of n inertias by hand (see the module docstring)."""
    tg = grid(t_end, dt_out)
    sol = solve_ivp(chain_rhs(n), (0.0, t_end), np.zeros(2 * n), method=method, t_eval=tg, rtol=rtol,
                    atol=rtol * 1e-2 if atol is None else atol)
    if not sol.success:
        raise RuntimeError(f"hand chain {n} ({method}): {sol.message}")
    return {f"J{i}.w": sol.y[n + i] for i in sorted({0, n // 2, n - 1})}, {"nfev": sol.nfev}
