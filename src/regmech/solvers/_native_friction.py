"""The friction devices of the native IDA path (``ida_native``): their laws in closed form and the tables the
kernels read (``_native_kernels``, ``residual_friction`` and ``events``).

A friction device is served when it states its law in closed form, linear in one signal
(``FrictionDevice.linear_law``: normal force ``fn = s u(t)`` [N], kinetic torque ``k max(fn, 0)`` at every
speed, static capacity ``peak`` times that), or, for a one-way clutch, ``one_way_law`` (the same, plus the
small capacity that holds its freewheel when disengaged). In a segment's modes its row is ``G_f a = 0``
(stuck), ``lam - mode k max(fn, 0)`` (sliding) or ``lam`` (free, held); its first event function is that of
``hybrid.events`` for the mode:

* sliding: ``mode w_rel``; stuck: ``tau0_max - |lam|``; free or held: 1;
* a one-way clutch stuck: ``tau0_max - lam`` (it releases forward only; ``tau0_max`` is ``peak k fn``
  engaged, the freewheel's small capacity disengaged); free: ``w_rel`` (it locks where ``w_rel`` reaches 0);

and its second the engagement, ``fn`` engaged, ``-fn`` not. Lossy gears, speed-dependent friction and
devices whose normal force is read from the state run the Python callbacks (``friction_laws`` says which).
"""

from __future__ import annotations

import numpy as np

from ..modes import FREE

def friction_laws(fr):
    """Per friction device its closed-form law (module docstring) as ``(signal entry, fn_scale, k, peak,
    one_way, free_capacity)``, or a string naming the first device the kernels cannot evaluate. Kept with the compiled system (``fr.c``; dropped with it on any change of the
    model)."""
    kept = fr.c.__dict__
    if "_native_friction_laws" not in kept:
        kept["_native_friction_laws"] = _friction_laws(fr)
    return kept["_native_friction_laws"]


def _friction_laws(fr):
    """``friction_laws`` computed."""
    from ..compile._native_signals import SUPPORTED_POOLED, signal_entry
    laws = []
    for j, dev in enumerate(fr.devices):
        what = f"{type(dev).__name__} '{dev.name}'"
        if getattr(dev, "impact", False):
            return f"{what} (rigid impacts: the speeds jump at events, applied in Python)"
        if dev.coupled:
            return f"{what} (lossy gears run their mode logic, shared with their holders, in Python)"
        if fr.inputs[j]:
            return (f"{what} reads inputs from the state (a thermal mass's temperature or a controller's command "
                    f"as its normal force), which the native kernels do not evaluate")
        if dev.one_way:
            law = dev.one_way_law() if hasattr(dev, "one_way_law") else None
        else:
            law = dev.linear_law()
            law = None if law is None else tuple(law) + (0.0,)
        if law is None:
            return f"{what} has a speed-dependent or user-defined friction law"
        sig, fn_scale, k, peak, free_capacity = law
        entry = signal_entry(sig, pooled=True)
        if entry is None:
            return (f"{what} has a {type(sig).__name__} normal force (the native path evaluates "
                    f"{', '.join(SUPPORTED_POOLED)})")
        if not all(np.isfinite(x) for x in (fn_scale, k, peak, free_capacity)):
            return f"{what} has non-finite friction parameters"
        laws.append((entry, float(fn_scale), float(k), float(peak), bool(dev.one_way), float(free_capacity)))
    return laws


def _place_pool(pars, kinds, shift):
    """Move each table's first parameter (the index of its points, ``_native_signals.pooled_entries``) by
    ``shift``: its points then sit where the array that holds the parameters placed its pool."""
    from ..compile._native_signals import DERIVED, N_PAR, TABLE
    for i in np.nonzero(np.asarray(kinds) % DERIVED == TABLE)[0]:
        pars[N_PAR * i] += shift


class FrictionTables:
    """The kernels' friction data ``(hi, hf)`` (``_native_kernels`` module docstring) of compiled system ``c``
    in the solver's ordering ``order``, with ``set_segment`` writing the parts that belong to one segment."""

    def __init__(self, c, order, laws):
        from . import _native_kernels as K
        fr = c.friction
        N, mf = c.N, fr.mf
        self.K, self.c, self.mf = K, c, mf
        inv = np.arange(N) if order.perm is None else np.asarray(order.inv, np.int64)
        G = fr.G.tocsr()
        G.sum_duplicates()
        sptr, sidx, scoef, wptr, widx, wcoef = [0], [], [], [0], [], []
        for j in range(mf):
            cols = G.indices[G.indptr[j]:G.indptr[j + 1]]
            vals = G.data[G.indptr[j]:G.indptr[j + 1]]
            for k, g in zip(cols, vals):
                # the stuck row reads the acceleration a_k: y' of the speed, or y of its dummy derivative
                sidx.append(int(c.iad[c.pos_in_Dv[k]]) if c.is_dummy_v[k] else N + int(c.iv[k]))
                scoef.append(float(g))
                widx.append(int(inv[c.iv[k]]))
                wcoef.append(float(g))
            sptr.append(len(sidx))
            wptr.append(len(widx))
        lam = np.asarray(c.ilam[fr.offset:fr.offset + mf], np.int64)
        self.lam_compiled = lam
        from ..compile._native_signals import pooled_entries
        kinds, sig_par, pool = pooled_entries([law[0] for law in laws], 0)
        parts_i = [inv[c.r_fric], sptr, sidx, wptr, widx, lam, inv[lam], kinds,
                   np.zeros(mf), np.zeros(mf), np.zeros(mf), np.full(mf, -1)]
        offs, pos = [], 14
        for a in parts_i:
            offs.append(pos)
            pos += len(a)
        self.hi = np.concatenate([np.array([mf] + offs + [pos], np.int64)] +
                                 [np.asarray(a, np.int64) for a in parts_i])
        self._mode, self._evkind, self._engaged, self._relief = (slice(offs[k], offs[k] + mf) for k in (8, 9, 10, 11))
        parts_f = [scoef, wcoef, sig_par, [law[1] for law in laws], [law[2] for law in laws],
                   [law[3] for law in laws], np.zeros(mf), np.zeros(mf), [law[5] for law in laws], pool]
        offs, pos = [], 10
        for a in parts_f:
            offs.append(pos)
            pos += len(a)
        # a table's points follow the last part: its first parameter, relative to the parameters' start, moved
        _place_pool(sig_par, kinds, offs[9] - len(sig_par))
        self.hf = np.concatenate([np.array(offs[:9] + [pos], float)] + [np.asarray(a, float) for a in parts_f])
        self.one_way = [law[4] for law in laws]
        self._ms, self._tol = slice(offs[6], offs[6] + mf), slice(offs[7], offs[7] + mf)
        self._inv = inv

    def set_segment(self, modes, engaged, relief):
        """Write the segment's modes, event kinds, engagement and relief events (``hybrid.events``); plain
        Python on the few devices of a model (numpy's per-call overhead would be most of it)."""
        K, hi, hf = self.K, self.hi, self.hf
        m0, e0, g0, r0 = self._mode.start, self._evkind.start, self._engaged.start, self._relief.start
        s0, t0 = self._ms.start, self._tol.start
        for j in range(self.mf):
            m = int(modes[j])
            hi[m0 + j] = m
            if self.one_way[j]:
                kind = K.EV_STUCK_ONE_WAY if m == 0 else K.EV_FREE_ONE_WAY if m == FREE else K.EV_SLIDING
            else:
                kind = K.EV_STUCK if m == 0 else K.EV_SLIDING if m in (1, -1) else K.EV_CONSTANT
            hi[e0 + j] = kind
            hi[g0 + j] = 1 if engaged[j] else 0
            hi[r0 + j] = -1
            hf[s0 + j] = 0.0
            hf[t0 + j] = 0.0
        for j, il, sign, tol in relief:
            hi[r0 + j] = self._inv[il]
            hf[s0 + j] = float(modes[j]) * sign
            hf[t0 + j] = tol


