"""First-order state space of any compiled model about an operating point.

The compiled DAE ``F(t, y, y', u) = 0`` (``CompiledSystem``: positions and speeds, dummy accelerations,
constraint forces, device states, block outputs) is linearised at a consistent point ``(y0, y0')``:

    F_y dy + F_y' dy' + F_u du = 0.

Its unknowns split into the *differential* ones ``d`` (positions and speeds of the independent coordinates,
the differential device states: currents, integrators, filters) and the *algebraic* ones ``a`` (dummy
coordinates, constraint forces, block outputs); ``y'`` enters through ``d`` only. The form is of index 1
(IDA solves it so), so ``E = [F_y'[:, d]  F_y[:, a]]`` is nonsingular and

    [dd'; da] = -E^-1 (F_y[:, d] dd + F_u du),

which gives ``dd' = A dd + B du`` and ``da = K_d dd + K_u du``. An output that is a linear function of the
unknowns, ``dz = c . dy``, is ``C dd + D du`` with ``C = c_d + c_a K_d`` and ``D = c_a K_u``.

``F_y`` and ``F_y'`` are the compiled Jacobian itself (``CompiledSystem.jacobian_data`` at ``cj = 0`` and its
change per unit ``cj``): exact for the device laws (their symbolic derivatives), the friction rows in their
modes (stuck rows rigid, sliding ones with the slope of their characteristic), the constraints. ``F_u`` is
exact too: the derivative of the laws of the device owning input ``u`` (a signal parameter such as a
``Torque``'s ``tau``, a motor's ``u``, a controller's ``ref``), written symbolically once per class. States
that only change at events (sample-and-hold values, branch states of switches) are held at their values.

Inputs are named ``"<device>.<parameter>"``; outputs ``"<mass>.phi"``/``".w"`` (``.s``/``.v``), a device's
``phi_rel``/``w_rel`` (its first row), and any device state or block output (``"pi.y"``, ``"mot.i"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import sympy

from ..component import StateRead
from ..errors import ParameterError, StructureError
from .assembly import output_entries


@dataclass(eq=False)
class StateSpace:
    """``x' = A x + B u``, ``y = C x + D u`` (deviations from the operating point), with named ``states``,
    ``inputs`` and ``outputs`` (units of the model's signals: rad, rad/s, A, V, ...); ``t`` the instant,
    ``x0`` the values of the states there."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: list
    inputs: list
    outputs: list
    t: float
    x0: np.ndarray
    modes: np.ndarray = field(default=None, repr=False)

    def __repr__(self) -> str:
        return (f"StateSpace({len(self.states)} states, inputs {self.inputs}, outputs {self.outputs}, "
                f"t={self.t:g})")

    # -- modes -------------------------------------------------------------------------------------
    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` [1/s], sorted by real part, then imaginary part."""
        ev = la.eigvals(self.A) if len(self.A) else np.zeros(0, complex)
        return ev[np.lexsort((ev.imag, ev.real))]

    def natural_frequencies(self) -> np.ndarray:
        """``|lambda|`` [rad/s] of each pole (order of ``poles``)."""
        return np.abs(self.poles())

    def damping(self) -> np.ndarray:
        """Damping ratio ``-Re(lambda) / |lambda|`` of each pole (1 for a pole at 0)."""
        p = self.poles()
        mag = np.abs(p)
        return np.where(mag > 0, -p.real / np.where(mag > 0, mag, 1.0), 1.0)

    # -- frequency response ------------------------------------------------------------------------
    def frequency_response(self, omega) -> np.ndarray:
        """``G(i w) = C (i w I - A)^-1 B + D``, shape ``(len(omega), outputs, inputs)``; ``omega`` [rad/s]."""
        omega = np.atleast_1d(np.asarray(omega, float))
        n = len(self.A)
        out = np.empty((len(omega), len(self.outputs), len(self.inputs)), complex)
        for k, w in enumerate(omega):
            X = np.linalg.solve(1j * w * np.eye(n) - self.A, self.B) if n else np.zeros((0, len(self.inputs)))
            out[k] = self.C @ X + self.D
        return out

    def bode(self, omega=None, input=None, output=None):
        """``(omega [rad/s], magnitude, phase [deg])`` from ``input`` to ``output`` (names; default the first
        of each); ``omega`` default: 400 points over three decades around the poles."""
        i = self._index(self.inputs, input, "input")
        o = self._index(self.outputs, output, "output")
        if omega is None:
            w = self.natural_frequencies()
            w = w[w > 0]
            lo, hi = (w.min() / 100, w.max() * 100) if len(w) else (1e-2, 1e2)
            omega = np.logspace(np.log10(lo), np.log10(hi), 400)
        G = self.frequency_response(omega)[:, o, i]
        return np.asarray(omega, float), np.abs(G), np.degrees(np.unwrap(np.angle(G)))

    @staticmethod
    def _index(names, name, what):
        if name is None:
            if not names:
                raise ParameterError(f"the state space has no {what}s")
            return 0
        if name not in names:
            raise ParameterError(f"no {what} '{name}' in the state space; its {what}s are {names}")
        return names.index(name)

    # -- conversions -------------------------------------------------------------------------------
    def to_scipy(self):
        """A ``scipy.signal.StateSpace`` of ``(A, B, C, D)``."""
        from scipy.signal import StateSpace as ScipySS
        return ScipySS(self.A, self.B, self.C, self.D)

    def to_control(self):
        """A python-control ``StateSpace`` with the names (needs the optional extra ``control``); python-control
        allows no '.' in a signal name, so ``"pi.ref"`` is called ``"pi_ref"`` there."""
        try:
            import control
        except ImportError as exc:
            raise ImportError("to_control() needs python-control: pip install 'regmech[control]'") from exc

        def names(lst):
            return [n.replace(".", "_") for n in lst]
        return control.ss(self.A, self.B, self.C, self.D, states=names(self.states), inputs=names(self.inputs),
                          outputs=names(self.outputs))


# ================================================================================ building
def state_space(c, y, yp, t: float, modes, inputs=None, outputs=None) -> StateSpace:
    """The ``StateSpace`` of compiled system ``c`` at the consistent point ``(y, yp)`` at ``t`` (module
    docstring); ``inputs``/``outputs`` lists of names (None: every signal parameter of a device that is not
    read from the unknowns / every state)."""
    t = float(t)
    modes = np.asarray(modes, int) if modes is not None else c.modes0
    Fy, Fyp = _jacobians(c, t, y, yp, modes)
    held = _held_states(c)
    keep_rows = np.setdiff1d(np.arange(c.N), c.r_z[held])
    keep_cols = np.setdiff1d(np.arange(c.N), c.iz[held])
    diff = np.setdiff1d(keep_cols, c.algebraic)      # positions, speeds of masses, differential states
    alg = np.setdiff1d(keep_cols, diff)
    Fy, Fyp = Fy[keep_rows], Fyp[keep_rows]
    E = np.hstack([Fyp[:, diff], Fy[:, alg]])
    in_names = _default_inputs(c) if inputs is None else list(inputs)
    Fu = np.zeros((c.N, len(in_names)))
    for j, name in enumerate(in_names):
        Fu[:, j] = _input_column(c, name, y, t)
    Fu = Fu[keep_rows]
    try:
        lu = la.lu_factor(E, check_finite=True)
    except (ValueError, la.LinAlgError) as exc:
        raise StructureError(f"linearize: the Jacobian at t={t:g} is not finite ({exc}); choose another point") \
            from exc
    if np.min(np.abs(np.diag(lu[0]))) <= 1e-14 * max(1.0, np.max(np.abs(np.diag(lu[0])))):
        raise StructureError(f"linearize: the model's equations are singular at t={t:g} (the algebraic unknowns "
                             f"are not determined by the state there); choose another point or other modes")
    X = -la.lu_solve(lu, np.hstack([Fy[:, diff], Fu]))
    nd = len(diff)
    A, B = X[:nd, :nd], X[:nd, nd:]
    Kd, Ku = X[nd:, :nd], X[nd:, nd:]
    names = _unknown_names(c)
    state_names = [names[k] for k in diff]
    out_names = state_names if outputs is None else list(outputs)
    Cy = np.vstack([_output_row(c, name, names) for name in out_names]) if out_names else np.zeros((0, c.N))
    C = Cy[:, diff] + Cy[:, alg] @ Kd
    D = Cy[:, alg] @ Ku
    return StateSpace(A, B, C, D, state_names, in_names, out_names, t, y[diff] + _datum(c, diff), modes)


def _jacobians(c, t, y, yp, modes):
    """``(F_y, F_y')`` dense at the point (the compiled Jacobian at cj = 0 and its change per unit cj)."""
    pat = c.jac.pattern

    def dense(cj):
        data = c.jacobian_data(t, y, yp, cj, modes)
        return sp.csc_matrix((data, pat.indices, pat.indptr), shape=pat.shape).toarray()

    J0 = dense(0.0)
    return J0, dense(1.0) - J0


def _held_states(c) -> np.ndarray:
    """Indices in z of the states that change only at events (sampled, branch states)."""
    held = [zi for zi, *_ in getattr(c, "sampled", ())] + [zi for zi, *_ in getattr(c, "branches", ())] + \
        [zi for zi, *_ in getattr(c, "latches", ())]
    return np.asarray(sorted(set(held)), int)


def _datum(c, cols) -> np.ndarray:
    """What each unknown's entry departs from (a thermal mass's temperature: its ambient)."""
    out = np.zeros(len(cols))
    for k, col in enumerate(cols):
        if col >= c.iz[0] if c.nz else False:
            out[k] = c.state_datum[col - c.iz[0]]
    return out


def _unknown_names(c) -> dict:
    """Index in y -> signal name, for positions, speeds and device states."""
    st = c.structure
    names = {}
    for k, node in enumerate(st.coord_node):
        if node.bodies:
            pn, wn, _, _ = node.bodies[0].var_names()
            names[int(c.ix[k])] = f"{node.bodies[0].name}.{pn}"
            names[int(c.iv[k])] = f"{node.bodies[0].name}.{wn}"
        else:
            names[int(c.ix[k])] = f"{st.coord_names[k]}.x"
            names[int(c.iv[k])] = f"{st.coord_names[k]}.v"
    for j, nm in enumerate(c.state_names):
        names[int(c.iz[j])] = nm
    return names


def _output_row(c, name, names) -> np.ndarray:
    """``c`` with ``output = c . y`` (linear in the unknowns), or ParameterError listing the outputs."""
    row = np.zeros(c.N)
    for col, nm in names.items():
        if nm == name:
            row[col] = 1.0
            return row
    st = c.structure
    dev_name, _, var = name.partition(".")
    dev = next((d for d in st.devices if d.name == dev_name), None)
    if dev is not None and dev.name in st.rows:
        rel = dev.rel_names.get(dev.domain, (None,) * 4)
        r0 = st.rows[dev.name][0]
        if var and var in (rel[0], rel[1]):
            target = c.ix if var == rel[0] else c.iv
            row[target[np.asarray(r0.cols, int)]] = r0.coefs
            return row
    have = sorted(set(names.values()))
    raise ParameterError(f"linearize: no linear output '{name}' in model '{c.model.name}'; outputs are the masses' "
                         f"positions and speeds, the devices' relative coordinates (phi_rel, w_rel) and the device "
                         f"states and block outputs: {have[:30]}{' ...' if len(have) > 30 else ''}")


def _default_inputs(c) -> list:
    """Every signal parameter of a kernel device that the laws read and that is no read of the unknowns."""
    out = []
    for g in c.groups:
        for dev in g.devices:
            out += [f"{dev.name}.{p}" for p in g.tpl.inputs]
    return out


_DERIVATIVES: dict = {}


def _input_column(c, name, y, t) -> np.ndarray:
    """``F_u`` of input ``name`` (``"<device>.<parameter>"``): the derivative of the device's laws by the
    parameter, placed in the residual rows its outputs feed."""
    dev_name, _, param = name.partition(".")
    hit = next(((g, i) for g in c.groups for i, d in enumerate(g.devices) if d.name == dev_name), None)
    if hit is None or param not in hit[0].tpl.inputs:
        dev = hit[0].devices[hit[1]] if hit else None
        if dev is not None and isinstance(dev._values.get(param), StateRead):
            raise ParameterError(f"linearize: input '{name}' reads {dev._values[param]!r}, a value of the model "
                                 f"itself, so it is no input; name a signal parameter, e.g. "
                                 f"{_default_inputs(c)[:6]}")
        raise ParameterError(f"linearize: no input '{name}' in model '{c.model.name}'; the inputs are the signal "
                             f"parameters the devices' laws read: {_default_inputs(c)}")
    g, i = hit
    tpl = g.tpl
    j = tpl.inputs.index(param)
    fn = _derivative_function(tpl, j)
    x, v, z = y[c._sx], y[c._sv], y[c._sz]
    e = c.Sc @ x + c.e0c
    de = c.Sc @ v
    args = [e[g.row_index[i, r]] for r in range(tpl.k)] + [de[g.row_index[i, r]] for r in range(tpl.k)] + \
           [z[g.state_index[i, s]] for s in range(len(tpl.states))] + \
           [z[g.read_index[i, q]] for q in range(len(tpl.reads))] + \
           [float(p[i]) for p in g.param_values] + [float(b.at(t)[i]) for b in g.banks] + [t]
    derivs = [float(d) for d in fn(*args)]
    col = np.zeros(c.N)
    outs = [("tau", r) for r in range(tpl.k)] + [("dz", s) for s in range(len(tpl.states))]
    for (oname, oi), d in zip(outs, derivs):
        if d == 0.0:
            continue
        ent, sign = output_entries(c, g, oname, oi)
        mine = ent.owner == i
        np.add.at(col, ent.index[mine], sign * ent.coef[mine] * d)
    return col


def _derivative_function(tpl, j):
    """``fn(args...) -> [d out / d input_j ...]`` over the template's outputs ``[tau..., dz...]``."""
    key = (id(tpl), j)
    fn = _DERIVATIVES.get(key)
    if fn is None:
        args, exprs = tpl.exprs["res"]
        sym = next(a for a in args if getattr(a, "name", None) == tpl.inputs[j])
        fn = sympy.lambdify(args, [sympy.diff(x, sym) for x in exprs], modules="numpy")
        _DERIVATIVES[key] = fn
    return fn


def operating_point(c, t, modes, x, v, z):
    """A consistent ``(y, y')`` at ``t`` from positions, speeds and device states (block outputs settled)."""
    return c.assemble_y(float(t), x, v, np.asarray(z, float), modes, rates=False)


__all__ = ["StateSpace", "state_space", "operating_point"]
