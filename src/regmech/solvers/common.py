"""What every solver shares: the output grid, time events, recording."""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError, SimulationError


def check_times(t_start, t_end, dt_out):
    for name, v in (("t_start", t_start), ("t_end", t_end)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ParameterError(f"simulate(): {name} must be a finite number, got {v!r}")
    if t_end <= t_start:
        raise ParameterError(f"simulate(): t_end ({t_end}) must be greater than t_start ({t_start})")
    if dt_out is None:
        dt_out = (t_end - t_start) / 500.0
    if not (isinstance(dt_out, (int, float)) and math.isfinite(dt_out) and dt_out > 0):
        raise ParameterError(f"simulate(): dt_out must be a positive number, got {dt_out!r}")
    return float(t_start), float(t_end), float(dt_out)


def output_grid(t_start, t_end, dt_out):
    n = int(math.floor((t_end - t_start) / dt_out + 1e-9))
    grid = t_start + dt_out * np.arange(n + 1)
    if t_end - grid[-1] > 1e-12 * max(1.0, abs(t_end)):
        grid = np.append(grid, t_end)
    grid[-1] = min(grid[-1], t_end)
    return grid


def signal_breakpoints(model, t_start, t_end):
    """Instants in (t_start, t_end) where some signal of the model is not smooth."""
    from ..signals import Signal
    pts = set()
    for comp in model.components.values():
        for val in comp._values.values():
            if isinstance(val, Signal):
                pts.update(b for b in val.breakpoints(t_start, t_end) if t_start < b < t_end)
    return sorted(pts)


class Recorder:
    """Collects output rows (t, y, yp, left flag, modes)."""

    def __init__(self, modes_width: int):
        self.t, self.y, self.yp, self.left, self.modes = [], [], [], [], []
        self.mw = modes_width

    def add(self, t, y, yp, modes, left=False):
        self.t.append(float(t))
        self.y.append(np.array(y, float))
        self.yp.append(np.array(yp, float))
        self.left.append(bool(left))
        self.modes.append(np.array(modes, int).copy())

    def arrays(self):
        Y = np.array(self.y)
        YP = np.array(self.yp)
        if not (np.all(np.isfinite(Y)) and np.all(np.isfinite(YP))):
            k = int(np.nonzero(~np.all(np.isfinite(Y), axis=1) | ~np.all(np.isfinite(YP), axis=1))[0][0])
            raise SimulationError(f"the solution became non-finite (NaN/inf) at t={self.t[k]:.6g}; the model or the "
                                  f"solver settings are unstable there (try a tighter tolerance or a stable solver)")
        modes = np.array(self.modes).reshape(len(self.t), self.mw)
        return np.array(self.t), Y, YP, np.array(self.left), modes


# ----------------------------------------------------------------- step budget
#: what a run that reaches its step budget can do instead (appended to the error message)
STEP_CAP_REMEDIES = ("use an implicit solver ('ida', 'scipy:Radau', 'scipy:BDF' or 'convolution'), reduce the "
                     "model with rm.Scene(model, ..., band_hz=...) (links above the band become rigid), loosen "
                     "rtol or shorten the run, or raise max_steps")


def check_link_spread(c, rtol, solver: str, stiff_check=True):
    """Refuse a tolerance that the link spread makes unreachable in double precision.

    A link ``spread = (w_max / w_min)^2`` times stiffer than the softest one
    (``link_frequencies``) turns the round-off of its elongation, ``eps |x|``,
    into a force error of ``eps * spread`` relative to the forces of the rest
    of the model, and the accelerations carry it. Beyond ``100 rtol`` the
    answer cannot meet ``rtol`` (measured on the 1e7 chain of the hard cases:
    errors of 1.3e-4 of the range at rtol 1e-8 with scipy Radau and LSODA) and
    an implicit method with error control crawls (IDA: Newton and the error
    test fail over and over). ``stiff_check=False`` runs it anyway.
    """
    if not stiff_check:
        return
    link = c.fastest_link()
    if link is None:
        return
    dev, w, ratio = link
    spread = ratio ** 2
    if np.finfo(float).eps * spread > 100 * rtol:
        raise SimulationError(
            f"solver '{solver}' on model '{c.model.name}': the stiffest link, {type(dev).__name__} '{dev.name}' "
            f"(local mode {w / 2 / np.pi:.3g} Hz), is {ratio:.3g} times faster than the softest; "
            f"the round-off of its force (eps * {spread:.3g} = {np.finfo(float).eps * spread:.2g} of the other "
            f"forces) exceeds what rtol={rtol:g} allows, so the answer cannot meet the tolerance. Make the link "
            f"rigid (Shaft(stiffness=None)) or let rm.Scene(band_hz=...) do it; stiff_check=False runs it anyway.")


#: smallest factor by which a small state's absolute tolerance is scaled down (``StateScale``)
ATOL_FLOOR = 1e-3


class StateScale:
    """The magnitude of each kind of state seen so far in a run, and the absolute tolerances it gives.

    A solver's state has kinds (positions, speeds, device states), each an
    index set (``kinds``: slices or index arrays into a vector of ``size``
    entries). ``m_k`` is the largest ``|u_i|`` of kind k so far in the run
    and, for a scalar ``atol``,

        atol_i = atol * clip(m_k / saturation, floor, 1)      (u_i of kind k)

    entries outside every kind keep ``atol``; an array ``atol`` is returned
    unchanged. So the scalar ``atol`` is the absolute tolerance of a motion
    of magnitude ``saturation`` (default 1: 1 m, 1 rad, 1 m/s, ...) or more,
    and a motion that stays small gets a proportionally smaller one: with
    the plain ``atol`` the error test of a state much smaller is absolute
    (``atol >> rtol |u|``), i.e. looser than ``rtol`` by ``atol / (rtol
    |u|)``. ``floor`` (default ``ATOL_FLOOR``) bounds the scaling. Per kind,
    not per state: a state that stays small beside large ones of its kind (a car the
    coupler wave has not reached yet) keeps its kind's tolerance, so it costs
    no extra steps. The scaling never loosens a tolerance. One object per
    run: its segments share it.
    """

    def __init__(self, atol, kinds, size, saturation=1.0, floor=ATOL_FLOOR):
        self.atol = atol
        self.scalar = np.ndim(atol) == 0
        self.saturation = float(saturation)
        self.floor = float(floor)
        self.size = int(size)
        self.kinds = [k for k in kinds if (len(range(self.size)[k]) if isinstance(k, slice) else len(k))]
        self.largest = np.zeros(len(self.kinds))

    def see(self, u):
        """Take the magnitudes of a state ``u`` (or of rows of states, ``u[..., i]``) into account."""
        u = np.asarray(u, float)
        for k, idx in enumerate(self.kinds):
            part = u[..., idx]
            if part.size:
                self.largest[k] = max(self.largest[k], float(np.max(np.abs(part))))

    def factors(self):
        """``clip(m_k / saturation, floor, 1)`` per kind."""
        return np.clip(self.largest / self.saturation, self.floor, 1.0)

    def tolerances(self):
        if not self.scalar:
            return self.atol
        out = np.full(self.size, float(self.atol))
        for f, idx in zip(self.factors(), self.kinds):
            out[idx] = float(self.atol) * f
        return out


class StepBudget:
    """The steps of one whole run (every segment) against ``max_steps``; shared by the run's steppers.

    A stepper calls ``charge(stepper, problem)`` after every accepted step;
    when the run has taken more than ``max_steps`` steps it stops with a
    ``SimulationError`` that says where (time reached, last step size) and
    why: for an explicit method (``stability_bound`` = the ``h * rho`` up to
    which it is stable on the negative real axis) whether the last step sat
    at the stability limit set by the spectral radius ``rho`` of ``dg/du``
    (stiff for the method) or below it (the steps are set by the tolerance:
    a long run for the method's order); in both cases the fastest link is
    named (``CompiledSystem.link_frequencies``), with the number of its
    periods in the run. The cap is on accepted steps, the unit the run's
    ``Stats.steps`` reports; the cost of one step (which sets what a refused
    run costs) is measured per solver where the default is chosen.
    """

    def __init__(self, name: str, max_steps: int, t_end: float, stability_bound: float | None = None):
        if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
            raise ParameterError(f"solver '{name}': max_steps must be a positive integer, got {max_steps!r}")
        self.name = name
        self.max_steps = int(max_steps)
        self.t_end = float(t_end)
        self.stability_bound = stability_bound
        self.steps = 0

    def charge(self, stepper, problem) -> None:
        self.steps += 1
        if self.steps > self.max_steps:
            raise self.error(stepper, problem)

    def error(self, stepper, problem) -> SimulationError:
        c = problem.c
        t, h = float(stepper.t), float(stepper.t - stepper.t_old)
        where = (f"solver '{self.name}' took more than max_steps={self.max_steps} steps in model "
                 f"'{c.model.name}' and stopped at t={t:.6g} s of t_end={self.t_end:.6g} s (last step "
                 f"h={h:.3g} s)")
        why, stiff = self._diagnosis(stepper, problem, h)
        named = c.stiffness_hint(always=True) if stiff else ""
        link = c.fastest_link()
        if not named and link is not None:
            dev, w, _ = link
            named = (f" The fastest link is {type(dev).__name__} '{dev.name}' (local mode {w / 2 / math.pi:.3g} Hz, "
                     f"about {w / (2 * math.pi) * self.t_end:.3g} periods in the run).")
        return SimulationError(f"{where}: {why}.{named} To finish: {STEP_CAP_REMEDIES}.")

    def _diagnosis(self, stepper, problem, h) -> tuple[str, bool]:
        """Why the run needs so many steps, and whether the stiffness of the model is the reason."""
        if self.stability_bound is None:
            return ("the steps are set by the tolerance (this implicit method has no stability limit on them): "
                    "the run is long for this rtol, or the model moves fast everywhere"), False
        from .ode_driver import _spectral_radius
        rho = _spectral_radius(problem, stepper.t, stepper.u)
        if not rho or h <= 0:
            return "an explicit method that needs this many steps is usually held back by stiffness", True
        ratio = h * rho / self.stability_bound
        if ratio > 0.3:
            more = (self.t_end - stepper.t) * rho / self.stability_bound
            return (f"h * rho = {h * rho:.3g} with the spectral radius rho = {rho:.3g} 1/s of the Jacobian, at "
                    f"the stability limit {self.stability_bound:g} of this explicit method: the model is stiff "
                    f"for it (about {more:.3g} more steps to go)"), True
        return (f"h * rho = {h * rho:.3g} is well below this method's stability limit {self.stability_bound:g} "
                f"(rho = {rho:.3g} 1/s): the steps are set by the tolerance, i.e. the run is long for this "
                f"method's order at this rtol (a higher-order method such as 'scipy:DOP853' takes fewer "
                f"steps)"), False
