"""Signal parameters read from the unknowns, algebraic device states and sampled states.

A device's signal parameter may hold a ``component.StateRead`` instead of a function of time: the value of
state ``key`` of another device (a causal block's output, ``regmech.blocks``). The kernel template then has
that parameter as an argument ``r`` after the device's own states (``kernels.template_for``); here each read
is placed: ``KernelGroup.read_index[i, j]`` is the index in ``z`` of the state that read ``j`` of instance
``i`` takes. The Jacobian entries ``d law / d r`` go to that state's column of ``y`` like any other
argument's (``assembly.input_entries``), so the residual, the Jacobian, the switching surfaces, the friction
inputs and the outputs see the read as they see the device's own states.

A state listed in ``Device.algebraic_states`` is an algebraic unknown: ``derivatives()`` gives ``f - s`` for
the equation ``s = f(...)`` and the compiler writes the row ``s - f = 0`` without ``s'`` (``algebraic_rows``).
Its value at a restart comes from ``settle``: the fixed point ``s <- f`` swept once per level of the graph
of reads (exact for an acyclic graph). A cycle of algebraic states that depend directly on each other (an
algebraic loop through direct feedthrough) is refused at compile time (``_check_loops``), naming the devices.

A state listed in ``Device.sampled_states`` is held: its rate is 0, and at every instant ``t0 + k T`` (the
device's period ``T`` > 0 and offset ``t0``, time events of the run: the device declares them as a signal's
breakpoints) it takes the value of its input parameter (``sample``), i.e. a sample-and-hold.
"""

from __future__ import annotations

import math

import numpy as np

from ..component import StateRead
from ..errors import ModelError


def attach(c) -> None:
    """Place every read of ``c.groups``, mark algebraic and sampled states, refuse algebraic loops."""
    index = _state_index(c)
    alg = np.zeros(c.nz, bool)
    c.sampled = []                  # (z index, input: z index or Signal, period, offset, device)
    for g in c.groups:
        reads = g.tpl.reads
        for i, dev in enumerate(g.devices):
            for j, p in enumerate(reads):
                g.read_index[i, j] = _producer(index, dev, p)
            names = list(type(dev).states)
            for s in getattr(type(dev), "algebraic_states", ()):
                alg[int(g.state_index[i, names.index(s)])] = True
            for s, (inp, period, offset) in getattr(type(dev), "sampled_states", {}).items():
                val = dev._values[inp]
                source = _producer(index, dev, inp) if isinstance(val, StateRead) else val
                c.sampled.append((int(g.state_index[i, names.index(s)]), source, float(dev._values[period]),
                                  float(dev._values[offset]), dev))
    _refuse_unread(c)
    c.branches = _branches_of(c, "branch_states")
    c.latches = _branches_of(c, "latch_states")
    c.z_algebraic = alg
    c.n_alg = int(alg.sum())
    c.has_reads = any(g.tpl.reads for g in c.groups)
    c._alg_levels = _check_loops(c) if c.n_alg else 0
    #: states only the DAE form holds (algebraic, sampled, branch states): the ODE form refuses the model
    c.dae_only = bool(c.n_alg or c.sampled or c.branches or c.latches)
    #: the surfaces of latch states (``hybrid.surfaces`` takes their side from their sign after a crossing)
    c.latch_surfaces = np.array(sorted({k for _, k, _, _ in c.latches}), int)


def _branches_of(c, attr) -> list:
    """Branch states (``Device.branch_states``): ``(z index, surface index, device)``; latch states
    (``Device.latch_states``): ``(z index, surface index, increment, device)``, one entry per surface."""
    out = []
    for g, start, active in getattr(c, "surface_groups", ()):
        pos = {int(i): k for k, i in enumerate(range(g.n) if active is None else active)}
        n_act = len(pos)
        for i, dev in enumerate(g.devices):
            if i not in pos:
                continue
            for s, spec in getattr(type(dev), attr, {}).items():
                zi = int(g.state_index[i, list(g.tpl.states).index(s)])
                if attr == "branch_states":
                    out.append((zi, start + spec * n_act + pos[i], dev))
                else:
                    out += [(zi, start + kk * n_act + pos[i], float(inc), dev) for kk, inc in spec]
    return out


def _refuse_unread(c) -> None:
    """``ModelError`` for a value of the unknowns given to a parameter that is read as a function of time only
    (a device that is no kernel: a prescribed motion's reference, a friction device's parameter other than its
    normal force)."""
    for dev in c.structure.devices:
        if dev.device_kind() == "compliant":
            continue
        for p, val in dev._values.items():
            if not isinstance(val, StateRead) or (dev.device_kind() == "friction"
                                                   and p == getattr(dev, "_force_param", None)):
                continue
            raise ModelError(
                f"{type(dev).__name__} '{dev.name}': parameter '{p}' reads {val!r}, a value of the unknowns, but "
                f"this device reads '{p}' as a function of time only (a prescribed motion needs its "
                f"derivatives); drive the mass through a Torque/Force source (tau={val!r}) instead, or give "
                f"'{p}' a signal")


def _state_index(c) -> dict:
    """``(id(device), state) -> index in z`` of every kernel state."""
    out = {}
    for g in c.groups:
        for i, dev in enumerate(g.devices):
            for s, name in enumerate(g.tpl.states):
                out[(id(dev), name)] = int(g.state_index[i, s])
    return out


def _producer(index, dev, param) -> int:
    ref = dev._values[param]
    hit = index.get((id(ref.device), ref.key))
    if hit is None:
        prod = ref.device
        raise ModelError(
            f"{type(dev).__name__} '{dev.name}': parameter '{param}' reads {ref!r}, but {type(prod).__name__} "
            f"'{prod.name}' is not part of this model; add it with model.add({prod.name!r} ...) before simulating")
    return hit


def _check_loops(c) -> int:
    """The depth of the graph of algebraic states (edges: a state whose equation reads another algebraic state
    directly); ``ModelError`` naming the devices of a cycle."""
    import networkx as nx
    G = nx.DiGraph()
    owner = {}
    for g in c.groups:
        alg_of = [s for s in range(len(g.tpl.states))]
        for i, dev in enumerate(g.devices):
            for s in alg_of:
                zi = int(g.state_index[i, s])
                if c.z_algebraic[zi]:
                    G.add_node(zi)
                    owner[zi] = dev
            for (oname, oi), (wname, wj) in g.tpl.jac_entries:
                if oname != "dz":
                    continue
                zo = int(g.state_index[i, oi])
                if not c.z_algebraic[zo]:
                    continue
                src = int(g.read_index[i, wj]) if wname == "r" else int(g.state_index[i, wj]) if wname == "z" else None
                if src is not None and src != zo and c.z_algebraic[src]:
                    G.add_edge(src, zo)
    try:
        cycle = nx.find_cycle(G)
    except nx.NetworkXNoCycle:
        return int(nx.dag_longest_path_length(G)) + 1 if G.number_of_nodes() else 0
    names = []
    for a, _ in cycle:
        dev = owner[a]
        label = f"{type(dev).__name__} '{dev.name}'"
        if label not in names:
            names.append(label)
    raise ModelError(
        f"algebraic loop through direct feedthrough: {' -> '.join(names + names[:1])}; each output depends at the "
        f"same instant on the next one's, so no order of evaluation exists. Break the loop with a block that has "
        f"a state: a Lag (first order, time constant T), an Integrator, or a SampleHold")


def algebraic_rows(c) -> np.ndarray:
    """Boolean mask over ``z`` of the algebraic states (their rows carry no ``z'``)."""
    return c.z_algebraic if hasattr(c, "z_algebraic") else np.zeros(c.nz, bool)


def settle(c, t, x, v, z) -> np.ndarray:
    """``z`` with its algebraic states solving their equations at ``(t, x, v)`` (``z`` modified in place), the
    sampled states taking their inputs at a sample instant ``t``."""
    if not c.n_alg and not c.sampled and not c.branches and not c.latches:
        return z
    _fixed_point(c, t, x, v, z)
    sample = bool(c.sampled)
    for _ in range(len(c.branches) + LATCH_MAX + 2):
        changed = _sides(c, t, x, v, z) if c.branches else False
        if c.latches:
            changed = _latch(c, t, x, v, z) or changed
        if sample:
            changed = _sample(c, t, z) or changed
            sample = False
        if not changed:
            break
        _fixed_point(c, t, x, v, z)
    return z


#: a switching surface's value below this in magnitude is on the surface (its sign is round-off)
SIDE_TOL = 1e-9
#: latch changes at one restart at most (a gear selection settling from first to the right gear at the start)
LATCH_MAX = 32


def _latch(c, t, x, v, z) -> bool:
    """Grow the latch states whose surface is above zero (clearly, or on it just after the run crossed it:
    ``hybrid.surfaces`` flipped its side); returns whether one changed. Each change puts its surface back
    below zero (the device's design), so the next call finds nothing more to do."""
    y = np.zeros(c.N)
    y[c._sx], y[c._sv], y[c._sz] = x, v, z
    g = c.surface_values(t, y)
    kept = c.__dict__.get("surface_sides")
    for zi, k, inc, _ in c.latches:
        if g[k] > SIDE_TOL or (kept is not None and kept[k] > 0 and g[k] > -SIDE_TOL):
            z[zi] += inc
            return True             # one change at a time: the surfaces depend on the state
    return False


def _sides(c, t, x, v, z) -> bool:
    """Set the branch states from the sides of their surfaces: the signs of the surfaces at ``(t, x, v, z)``,
    but for those on the surface (``|g| <= SIDE_TOL``), which keep the side the event logic gives them during a
    run (``hybrid.surfaces`` writes them, flipped at a crossing). Returns whether one changed."""
    y = np.zeros(c.N)
    y[c._sx], y[c._sv], y[c._sz] = x, v, z
    g = c.surface_values(t, y)
    sides = np.where(g < 0.0, -1.0, 1.0)
    kept = c.__dict__.get("surface_sides")
    if kept is not None:
        # on a surface (a crossing's instant, or a limit held) the sign of g is round-off: the run's side holds
        sides = np.where(np.abs(g) > SIDE_TOL, sides, kept)
    changed = False
    for zi, k, _ in c.branches:
        val = 1.0 if sides[k] > 0 else 0.0
        changed = changed or val != z[zi]
        z[zi] = val
    return changed


def _fixed_point(c, t, x, v, z) -> None:
    if not c.n_alg:
        return
    plan = c._plan
    alg = c.z_algebraic
    left = t >= c._t_right
    for _ in range(c._alg_levels + 1):
        out = plan.device_outputs(x, v, z, t, left, c._sx, c._sv, c._sz)
        step = out[plan.n_c:][alg]
        z[alg] += step
        if not np.all(np.isfinite(z[alg])):
            bad = [c.state_names[k] for k in np.nonzero(alg)[0] if not np.isfinite(z[k])]
            raise ModelError(f"the block outputs {bad} are not finite at t={t:.6g}; check the blocks' parameters "
                             f"and the signals they read")


def is_sample_instant(t: float, period: float, offset: float) -> bool:
    """Whether ``t`` is one of ``offset + k period`` (k >= 0), to the round-off of the instants' formula."""
    k = round((t - offset) / period)
    return k >= 0 and abs(t - (offset + k * period)) <= 1e-9 * period + 1e-14 * abs(t)


def _sample(c, t, z) -> bool:
    changed = False
    for zi, source, period, offset, _ in c.sampled:
        if not is_sample_instant(t, period, offset):
            continue
        val = z[source] if isinstance(source, (int, np.integer)) else source.value(t, False)
        if not math.isfinite(val):
            raise ModelError(f"the sampled input of '{c.state_names[zi]}' is not finite at t={t:.6g}")
        changed = changed or val != z[zi]
        z[zi] = val
    return changed


def refuse_ode_form(c) -> None:
    """``ModelError`` for a model whose algebraic block outputs the ODE form cannot hold."""
    if getattr(c, "dae_only", False):
        names = sorted({n.rpartition(".")[0] for k, n in enumerate(c.state_names) if c.z_algebraic[k]}
                       | {s[4].name for s in c.sampled} | {b[2].name for b in c.branches}
                       | {b[3].name for b in c.latches})
        what = []
        if names:
            what.append(f"causal blocks ({', '.join(names[:6])}{' ...' if len(names) > 6 else ''}) whose outputs "
                        f"are algebraic unknowns or sampled states")
        points = [c.structure.coord_names[k] for k in getattr(c, "massless", ())]
        if points:
            what.append(f"massless points ({', '.join(points[:6])}) whose speeds are algebraic unknowns")
        raise ModelError(
            f"model '{c.model.name}' has {' and '.join(what)}, which the ODE form of explicit and expm solvers "
            f"cannot hold; run it with solver='ida' or 'auto'")


class Recorded:
    """A read parameter's values over a run's output rows, as a signal: ``value(t, left)`` at an output
    instant (the row with that ``t`` and ``left`` flag). ``Device.derived`` reads its signal parameters
    with ``value``; a parameter read from the unknowns is replaced by this while it runs."""

    def __init__(self, T, L, values):
        self.T, self.L, self.values = np.asarray(T, float), np.asarray(L, bool), np.asarray(values, float)

    def value(self, t, left=False):
        hits = np.nonzero(self.T == t)[0]
        if not len(hits):
            return float(np.interp(t, self.T, self.values))
        for i in hits:
            if bool(self.L[i]) == bool(left):
                return float(self.values[i])
        return float(self.values[hits[0]])

    def derivative(self, t, order=1, left=False):
        return float(np.interp(t, self.T, np.gradient(self.values, self.T))) if order == 1 else 0.0


def state_column(c, dev, key) -> int | None:
    """Index in ``z`` of state ``key`` of ``dev`` (a kernel device of ``c``), or None."""
    return _state_index(c).get((id(dev), key))


class recorded_reads:
    """``with recorded_reads(c, dev, T, L, Y):`` the parameters of ``dev`` read from the unknowns hold their
    values over the rows ``Y`` (``Recorded``) for the block's duration."""

    def __init__(self, c, dev, T, L, Y):
        self.c, self.dev, self.T, self.L, self.Y = c, dev, T, L, Y
        self.saved = {}

    def __enter__(self):
        for p, val in list(self.dev._values.items()):
            if isinstance(val, StateRead):
                zi = state_column(self.c, val.device, val.key)
                if zi is not None:
                    self.saved[p] = val
                    col = self.Y[:, self.c.iz[zi]] + self.c.state_datum[zi]
                    self.dev._values[p] = Recorded(self.T, self.L, col)
        return self

    def __exit__(self, *exc):
        self.dev._values.update(self.saved)
        return False
