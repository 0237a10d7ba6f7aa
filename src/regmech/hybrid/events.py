"""Event functions of friction and loss elements: what the solvers' root finding watches.

Two functions per device, each crossing zero *downwards* when its mode must change:

* stuck: ``tau0_max - |lam|`` (a freewheel: ``tau0_max - lam``, it holds any negative torque);
* sliding: ``mode * w_rel``; free: 1 (a freewheeling one-way clutch: ``w_rel``, it locks at 0); a sliding or
  freewheeling device at exactly zero slip gets ``1e-300`` (armed, see ``event_values``);
  held: 1 (the holders' functions decide);
* sliding at zero speed while other devices hold the motion (``Holding._relief_events``):
  ``mode * s * lam_holder + tol``, crossing when the holder starts to resist this
  device's kinetic torque instead of sharing the load with it;
* engagement: ``fn`` while engaged, ``-fn`` while not (a normal force of exactly zero
  is 'not yet engaged': a tiny positive value keeps IDA from deactivating a root
  function that is identically zero at the start);
* lossy gears give their own pair (``gears.gear_events``).

The capacities come from each device's ``capacity_function`` (``(t, left) -> (fn, tau0,
tau0_max)``, its parameters bound), the law the component states; a device whose laws read the
state (a thermal mass's temperature, a controller's command as normal force:
``compile.friction_inputs``) gets ``(t, left, q)`` with its inputs at the iterate's ``y``, so its
engagement and break-away functions are functions of the state.
"""

from __future__ import annotations

import numpy as np

from ..modes import FREE, HELD, STUCK
from ..signals import Constant, Step
from .gears import gear_events

#: what a device's first function is in the segment's modes (``_small_plan``)
_STUCK, _STUCK_ONE_WAY, _FREE_ONE_WAY, _CONSTANT, _SLIDING = range(5)


def _steady(cap_fn) -> bool:
    """True when a capacity function depends only on signals that are constant between their
    breakpoints: every solver ends a segment at those, so the value is the segment's."""
    signals = getattr(cap_fn, "signals", None)
    return signals is not None and all(type(s) in (Constant, Step) for s in signals)


class EventFunctions:
    """The event functions of a ``FrictionSet`` (mixin; state: ``engaged``, ``_relief``)."""

    def _setup_events(self):
        self.n_events = 2 * self.mf
        self.engaged = np.ones(self.mf, bool)      # engagement at the start of the current segment
        self._at_key, self._at_val = None, None
        self._at_segment = None                    # capacities at the segment's first call (``_at``)
        self._cap_fns = [d.capacity_function() for d in self.devices]
        # devices reading inputs from the state (``compile.friction_inputs``) are evaluated with them at each
        # call (``_with_inputs``), never from the time-only caches
        self._varying = [j for j, f in enumerate(self._cap_fns) if not _steady(f) and not self.inputs[j]]
        self._one_way = np.array([d.one_way for d in self.devices], bool)
        self._ev_key, self._ev_masks = None, None
        self._relief = []      # (row, holder's lam index, sign, tol): see Holding._relief_events
        self._small = None
        self._small_for, self._small_steps = None, None
        if self.mf <= 8 and not self._coupled_rows and not self.has_inputs and not self._stops:
            Gc = self.G.tocsr()
            c = self.c
            self._small = [([int(c.iv[k]) for k in Gc.indices[Gc.indptr[j]:Gc.indptr[j + 1]]],
                            [float(x) for x in Gc.data[Gc.indptr[j]:Gc.indptr[j + 1]]],
                            int(c.ilam[self.offset + j]), bool(self._one_way[j]), self._cap_fns[j])
                           for j in range(self.mf)]

    # -- pickling: the capacity functions are closures; they are made again from the devices ---------
    def __getstate__(self):
        state = self.__dict__.copy()
        state["_cap_fns"] = None
        state["_small_for"], state["_small_steps"] = None, None      # the plan holds them too
        if self._small is not None:
            state["_small"] = [row[:-1] for row in self._small]      # the last entry is the capacity function
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._cap_fns = [d.capacity_function() for d in self.devices]
        if self._small is not None:
            self._small = [(*row, fn) for row, fn in zip(self._small, self._cap_fns)]

    def _at(self, t, left):
        """Normal forces and (tau0, tau0_max) of every device at t, cached for the last t
        (IDA evaluates residual and event functions at the same instants). Devices whose capacities
        depend only on signals constant between breakpoints (``_steady``) keep the values of the
        segment's first call (``settle`` drops them); only the others are evaluated again."""
        key = (t, left)
        if self._at_key != key:
            if self._at_segment is None:
                vals = np.array([(0.0, 0.0, 0.0) if self.inputs[j] else f(t, left)
                                 for j, f in enumerate(self._cap_fns)]).reshape(self.mf, 3)
                self._at_segment = vals
            else:
                vals = self._at_segment.copy()
                for j in self._varying:
                    vals[j] = self._cap_fns[j](t, left)
            self._at_key, self._at_val = key, (vals[:, 0], vals[:, 1:])
        return self._at_val

    def _small_plan(self, modes, t, left):
        """What each device's first function needs in the segment's modes, in Python numbers.

        Made at the first call of a segment (``settle`` drops it; a plan belongs to one ``modes``
        array and one ``engaged`` array, the objects a segment runs with): the mode decides which
        function a device has, so the call does not test it again, and the first function of a
        free or held two-way device is the constant 1; the capacities of a device whose normal
        force is a ``Constant`` or a ``Step`` are those at ``t`` (the whole segment's). numpy
        scalars cost about 0.1 us an access, which for three clutches was most of the call.
        """
        plan = []
        for j, (cols, coefs, il, one_way, cap_fn) in enumerate(self._small):
            m = int(modes[j])
            if m == STUCK:
                kind = _STUCK_ONE_WAY if one_way else _STUCK
            elif m == FREE and one_way:
                kind = _FREE_ONE_WAY
            elif m == FREE or m == HELD:
                kind = _CONSTANT
            else:
                kind = _SLIDING
            # capacities that depend only on signals constant between breakpoints (time events, where a
            # segment ends) keep the value they have at any instant of the segment: evaluated once
            steady = cap_fn(t, left) if _steady(cap_fn) else None
            plan.append((kind, il, tuple(zip(cols, coefs)), float(m), cap_fn, bool(self.engaged[j]), steady))
        relief = [(2 * j, il, float(modes[j]) * sign, tol) for j, il, sign, tol in self._relief]
        self._small_for = (modes, self.engaged)
        self._small_steps = (plan, relief)

    def _event_values_small(self, t, left, y, modes):
        """The same functions in plain Python for a few devices without lossy gears: IDA calls them
        several times per step, and for three clutches numpy's per-call overhead dominates."""
        held = self._small_for
        if held is None or held[0] is not modes or held[1] is not self.engaged:
            self._small_plan(modes, t, left)
        plan, relief = self._small_steps
        y = y.tolist()
        out = []
        for kind, il, row, m, cap_fn, engaged, steady in plan:
            fn, _, tau0_max = steady or cap_fn(t, left)
            if kind == _SLIDING:
                w = 0.0
                for k, cf in row:
                    w += cf * y[k]
                g = m * w
                out.append(g if g != 0.0 else 1e-300)
            elif kind == _STUCK:
                out.append(tau0_max - abs(y[il]))
            elif kind == _CONSTANT:
                out.append(1.0)
            elif kind == _STUCK_ONE_WAY:
                out.append(tau0_max - y[il])
            else:
                w = 0.0
                for k, cf in row:
                    w += cf * y[k]
                out.append(w if w != 0.0 else 1e-300)
            out.append(fn if engaged else (-fn if fn != 0.0 else 1e-300))
        for o, il, ms, tol in relief:
            out[o] = ms * y[il] + tol
        return np.array(out)

    def event_values(self, t, y, yp, modes):
        """The ``2 * mf`` event functions at ``(t, y)`` in the segment's ``modes`` (module docstring);
        vectorised over the devices."""
        c = self.c
        left = t >= c._t_right
        if self._small is not None:
            return self._event_values_small(t, left, y, modes)
        w = self.w_rel(y[c.iv])
        lam_all = y[c.ilam]
        lam = lam_all[self.offset:]
        modes = np.asarray(modes)
        fns, caps = self._at(t, left)
        if self.has_inputs:
            fns, caps = fns.copy(), caps.copy()
            q = self.q_all(t, y)
            for j in self._q_devs:
                fns[j], caps[j, 0], caps[j, 1] = self._cap_fns[j](t, left, q[j])
        # masks depend on the segment's modes only: computed once per segment
        key = (modes.tobytes(), self.engaged.tobytes())
        if self._ev_key != key:
            stuck = modes == STUCK
            free = modes == FREE
            held = modes == HELD
            slide = ~stuck & ~free & ~held
            self._ev_masks = (stuck, stuck & self._one_way, stuck & ~self._one_way, free & self._one_way,
                              (free & ~self._one_way) | held, slide, np.where(slide, modes, 0))
            self._ev_key = key
        stuck, st_ow, st_2w, fr_ow, fr_2w, slide, sign = self._ev_masks
        first = sign * w
        # a device sliding at exactly zero speed (held by another one, see _share_redundant): a tiny
        # positive value keeps IDA from deactivating a root function identically zero at the start
        first[slide & (first == 0.0)] = 1e-300
        first[st_ow] = caps[st_ow, 1] - lam[st_ow]
        first[st_2w] = caps[st_2w, 1] - np.abs(lam[st_2w])
        # a freewheel left free at exactly zero slip: 1e-300, as a sliding device's (a function starting a segment at
        # zero is disarmed by the ODE driver until positive and left inactive by IDA: it would turn backward unseen)
        first[fr_ow] = np.where(w[fr_ow] != 0.0, w[fr_ow], 1e-300)
        first[fr_2w] = 1.0
        second = fns.copy()
        off = ~self.engaged
        second[off] = np.where(fns[off] != 0.0, -fns[off], 1e-300)
        out = np.empty(self.n_events)
        out[0::2], out[1::2] = first, second
        for j in self._coupled_rows:
            out[2 * j], out[2 * j + 1] = gear_events(
                self.devices[j], int(modes[j]), int(self.quadrant[j]), w[j], lam[j], lam_all[self.coupled[j]])
        for j, il, sign, tol in self._relief:
            out[2 * j] = modes[j] * sign * y[il] + tol
        if self._stops:
            self.stop_event_values(out, y, lam, modes)      # hard stops: limits reached, contact released
        return out
