"""Event functions of friction and loss elements: what the solvers' root finding watches.

Two functions per device, each crossing zero *downwards* when its mode must change:

* stuck: ``tau0_max - |lam|`` (a freewheel: ``tau0_max - lam``, it holds any negative torque);
* sliding: ``mode * w_rel``; free: 1 (a freewheeling one-way clutch: ``w_rel``, it locks at 0);
  held: 1 (the holders' functions decide);
* sliding at zero speed while other devices hold the motion (``Holding._relief_events``):
  ``mode * s * lam_holder + tol``, crossing when the holder starts to resist this
  device's kinetic torque instead of sharing the load with it;
* engagement: ``fn`` while engaged, ``-fn`` while not (a normal force of exactly zero
  is 'not yet engaged': a tiny positive value keeps IDA from deactivating a root
  function that is identically zero at the start);
* lossy gears give their own pair (``gears.gear_events``).

The capacities come from each device's ``capacity_function`` (``(t, left) -> (fn, tau0,
tau0_max)``, its parameters bound), the law the component states.
"""

from __future__ import annotations

import numpy as np

from ..modes import FREE, HELD, STUCK
from .gears import gear_events


class EventFunctions:
    """The event functions of a ``FrictionSet`` (mixin; state: ``engaged``, ``_relief``)."""

    def _setup_events(self):
        self.n_events = 2 * self.mf
        self.engaged = np.ones(self.mf, bool)      # engagement at the start of the current segment
        self._at_key, self._at_val = None, None
        self._cap_fns = [d.capacity_function() for d in self.devices]
        self._one_way = np.array([d.one_way for d in self.devices], bool)
        self._ev_key, self._ev_masks = None, None
        self._relief = []      # (row, holder's lam index, sign, tol): see Holding._relief_events
        self._small = None
        if self.mf <= 8 and not self._coupled_rows:
            Gc = self.G.tocsr()
            c = self.c
            self._small = [([int(c.iv[k]) for k in Gc.indices[Gc.indptr[j]:Gc.indptr[j + 1]]],
                            [float(x) for x in Gc.data[Gc.indptr[j]:Gc.indptr[j + 1]]],
                            int(c.ilam[self.offset + j]), bool(self._one_way[j]), self._cap_fns[j])
                           for j in range(self.mf)]
            self._ev_out = np.empty(self.n_events)

    # -- pickling: the capacity functions are closures; they are made again from the devices ---------
    def __getstate__(self):
        state = self.__dict__.copy()
        state["_cap_fns"] = None
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
        (IDA evaluates residual and event functions at the same instants)."""
        key = (t, left)
        if self._at_key != key:
            vals = np.array([f(t, left) for f in self._cap_fns]).reshape(self.mf, 3)
            self._at_key, self._at_val = key, (vals[:, 0], vals[:, 1:])
        return self._at_val

    def _event_values_small(self, t, left, y, modes):
        """The same functions in plain Python for a few devices without lossy gears: IDA calls them
        several times per step, and for three clutches numpy's per-call overhead dominates."""
        out = self._ev_out
        for j, (cols, coefs, il, one_way, cap_fn) in enumerate(self._small):
            m = modes[j]
            fn, tau0, tau0_max = cap_fn(t, left)
            if m == STUCK:
                lam = y[il]
                out[2 * j] = tau0_max - (lam if one_way else abs(lam))
            else:
                w = 0.0
                for k, cf in zip(cols, coefs):
                    w += cf * y[k]
                if m == FREE:
                    out[2 * j] = w if one_way else 1.0
                elif m == HELD:
                    out[2 * j] = 1.0
                else:
                    g = m * w
                    out[2 * j] = g if g != 0.0 else 1e-300
            out[2 * j + 1] = fn if self.engaged[j] else (-fn if fn != 0.0 else 1e-300)
        for j, il, sign, tol in self._relief:
            out[2 * j] = modes[j] * sign * y[il] + tol
        return out

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
        first[fr_ow] = w[fr_ow]
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
        return out
