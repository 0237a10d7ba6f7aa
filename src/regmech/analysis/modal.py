"""Free vibration: natural frequencies, mode shapes, damped eigenvalues.

Undamped modes solve the generalised symmetric eigenproblem

    C phi = w^2 M phi,      phi^T M phi = 1 (mass-normalised),

of the structural-matrix form (``compile.linear``); ``f = w / (2 pi)`` [Hz].
Rigid-body modes (``|w^2| <= rigid_tol * w^2_scale``) are reported as
exactly 0 Hz. Damped modes are the roots of the quadratic eigenproblem
``(lambda^2 M + lambda B + C) u = 0``, solved in the first-order companion
form

    [0  I] [u      ]          [I  0] [u      ]
    [-C -B] [lambda u] = lambda [0  M] [lambda u],

with ``lambda = -zeta w_n +- i w_n sqrt(1 - zeta^2)``: natural frequency
``|lambda| / 2 pi`` [Hz], damped frequency ``Im lambda / 2 pi`` [Hz],
damping ratio ``zeta = -Re lambda / |lambda|`` (1 for a real, overdamped
root). Large models: ``k`` lowest modes (nearest ``sigma`` [Hz]) by
shift-invert Lanczos (``scipy.sparse.linalg.eigsh``) on sparse matrices.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ParameterError, StructureError
from .table import Table

#: largest model solved densely when all modes are asked for (k=None)
DENSE_MAX = 4000
#: models up to this size are always solved densely (partial problems too)
DENSE_SMALL = 400
#: the same for the damped (companion, twice the size, non-symmetric) problem
DAMPED_DENSE_SMALL = 150
#: largest model whose damped roots are all computed at once (k=None)
DAMPED_DENSE_MAX = 1500


@dataclass
class DampedModes:
    """Roots of ``(lambda^2 M + lambda B + C) u = 0``, one per mode (``Im lambda >= 0``), by ``|lambda|``.

    ``eigenvalues`` [1/s] complex; ``natural_hz``, ``damped_hz`` [Hz];
    ``damping_ratio`` [-]; ``decay_rate = -Re lambda`` [1/s]; ``shapes``
    (nq x k complex, displacement part); ``oscillatory`` (complex pair).
    """

    eigenvalues: np.ndarray
    shapes: np.ndarray
    rigid: np.ndarray
    #: the undamped mode (0-based index into ``ModalResult``'s modes) each root belongs to, by the best
    #: match of shapes (``match_undamped``); -1 unmatched; None when computed without the undamped modes
    mode_index: np.ndarray | None = None

    @property
    def natural_hz(self) -> np.ndarray:
        return np.abs(self.eigenvalues) / (2 * np.pi)

    @property
    def damped_hz(self) -> np.ndarray:
        return self.eigenvalues.imag / (2 * np.pi)

    @property
    def decay_rate(self) -> np.ndarray:
        return 0.0 - self.eigenvalues.real    # 0.0 - x: no "-0" for rigid modes

    @property
    def damping_ratio(self) -> np.ndarray:
        mag = np.abs(self.eigenvalues)
        return np.where(mag > 0, -self.eigenvalues.real / np.where(mag > 0, mag, 1.0), 0.0)

    @property
    def oscillatory(self) -> np.ndarray:
        return self.eigenvalues.imag > 0

    def labels(self) -> list[str]:
        """Row label of each root: ``mode k`` with k the number of the undamped mode it belongs to (so both
        tables number modes alike; ``root j`` when not matched); a real root adds ``(real)`` (and a second
        real root of the same mode ``(real 2)``), a growing one ``(real, unstable)``."""
        out, seen = [], {}
        number = self.mode_index if self.mode_index is not None else np.arange(len(self.eigenvalues))
        for j, (lam, k) in enumerate(zip(self.eigenvalues, number)):
            base = f"mode {k + 1}" if k >= 0 else f"root {j + 1}"
            if lam.imag > 0 or lam == 0:
                out.append(base)
                continue
            seen[base] = seen.get(base, 0) + 1
            tag = "real, unstable" if lam.real > 0 else "real"
            out.append(f"{base} ({tag}{'' if seen[base] == 1 else ' ' + str(seen[base])})")
        counts: dict = {}
        for j, label in enumerate(out):           # labels stay unique (Table.row looks rows up by label)
            counts[label] = counts.get(label, 0) + 1
            if counts[label] > 1:
                out[j] = f"{label} #{counts[label]}"
        return out

    def table(self) -> Table:
        """Natural and damped frequency, damping ratio and decay rate per root, numbered by undamped mode
        (``labels``), with notes explaining real roots."""
        data = np.column_stack([self.natural_hz, self.damped_hz, self.damping_ratio, self.decay_rate])
        labels = self.labels()
        order = np.arange(len(labels))
        if self.mode_index is not None:
            key = np.where(self.mode_index >= 0, self.mode_index, len(labels) + np.arange(len(labels)))
            order = np.lexsort((np.abs(self.eigenvalues), key))
        notes = []
        real = (self.eigenvalues.imag == 0) & (self.eigenvalues != 0)
        if np.any(real & (self.eigenvalues.real < 0)):
            notes.append("(real): a real root, damping ratio 1: the motion decays without oscillating as "
                         "exp(-decay t) (an overdamped mode gives two of them; a rigid-body mode with damping "
                         "or a drag to the ground gives one besides 0)")
        if np.any(real & (self.eigenvalues.real > 0)):
            notes.append("(real, unstable): a real root > 0, shown with damping ratio -1 and a negative decay: "
                         "the motion grows as exp(|decay| t) without oscillating, so the operating point is "
                         "unstable (negative damping, e.g. a friction or tyre force falling with slip speed)")
        if np.any(self.eigenvalues == 0):
            notes.append("0 Hz rows: rigid-body modes (the masses turn or slide together freely)")
        return Table(data[order], [labels[i] for i in order],
                     ["natural [Hz]", "damped [Hz]", "damping ratio", "decay [1/s]"],
                     title="damped modes (numbered as the undamped modes they belong to)", index_name="mode",
                     notes=notes)


@dataclass
class ModalResult:
    """Undamped modes of a ``LinearModel`` (ascending), with the damped ones on demand.

    ``omega2`` [rad^2/s^2]; ``frequencies_hz``; ``rigid`` (bool, 0 Hz);
    ``shapes`` (nq x k, mass-normalised, largest full-coordinate entry
    positive); ``shapes_full`` (n x k, every coordinate); ``table()`` the
    shapes per mass (mode x mass name); ``damped`` the quadratic
    eigenproblem for the same number of modes; ``sensitivities()``.
    """

    lin: object = field(repr=False)
    omega2: np.ndarray
    shapes: np.ndarray = field(repr=False)
    rigid: np.ndarray
    scale: float = field(repr=False)
    k: int | None = None
    sigma: float = 0.0

    @property
    def frequencies_hz(self) -> np.ndarray:
        return np.where(self.rigid, 0.0, np.sqrt(np.abs(self.omega2))) / (2 * np.pi)

    @property
    def omega(self) -> np.ndarray:
        """Natural angular frequencies [rad/s] (0 for rigid-body modes)."""
        return 2 * np.pi * self.frequencies_hz

    @property
    def shapes_full(self) -> np.ndarray:
        return np.asarray(self.lin.T @ self.shapes)

    def mass_shapes(self, normalize: bool = True) -> Table:
        return self.table(normalize)

    def table(self, normalize: bool = True) -> Table:
        """Mode shapes per mass: rows ``mode i (f Hz)``, columns mass names.

        ``normalize``: scale each mode to a largest entry of +1 (otherwise the
        mass-normalised values, [rad or m] per sqrt(kg m^2 or kg)).
        """
        coords = self.lin.mass_coordinates()
        full = self.shapes_full
        data = np.array([full[k] for k in coords.values()]).T.reshape(len(self.omega2), len(coords))
        if normalize and data.size:
            peak = np.abs(data).max(axis=1, keepdims=True)
            data = data / np.where(peak > 0, peak, 1.0)
        index = [f"mode {i + 1} ({f:.4g} Hz)" for i, f in enumerate(self.frequencies_hz)]
        return Table(data, index, list(coords), title="mode shapes" + (" (max = 1)" if normalize else ""),
                     index_name="mode")

    def frequency_table(self) -> Table:
        """Undamped natural frequencies: ``f [Hz]``, ``w [rad/s]``, ``rigid`` (1 for a 0 Hz mode)."""
        data = np.column_stack([self.frequencies_hz, self.omega, self.rigid.astype(float)])
        return Table(data, [f"mode {i + 1}" for i in range(len(self.omega2))], ["f [Hz]", "w [rad/s]", "rigid"],
                     title="undamped natural frequencies", index_name="mode")

    @cached_property
    def damped(self) -> DampedModes:
        dm = damped_modes(self.lin, k=self.k, sigma=self.sigma, n_rigid=int(self.rigid.sum()), scale=self.scale)
        dm.mode_index = match_undamped(self, dm)
        return dm

    def sensitivities(self):
        from .sensitivity import sensitivities
        return sensitivities(self)

    def campbell(self, orders, speed_rpm=(500.0, 6000.0), **options):
        """Campbell diagram of these modes against engine ``orders`` over ``speed_rpm`` [rpm]
        (``analysis.campbell``; ``options``: ``shaft`` and ``ratio`` for another shaft's speed as the abscissa,
        ``operating_rpm``): ``.crossings``, ``.table()``, ``.plot(path)``."""
        from .campbell import campbell
        return campbell(self, orders, speed_rpm, model_name=self.lin.compiled.model.name, **options)

    @property
    def all_rigid(self) -> bool:
        """Every mode is a rigid-body mode (0 Hz): nothing elastic joins the masses at this operating point."""
        return bool(len(self.rigid)) and bool(np.all(self.rigid))

    def rigid_note(self) -> str:
        """One sentence for a model whose modes are all rigid-body modes (0 Hz): what that means."""
        n = len(self.rigid)
        masses = self.lin.mass_names
        shown = ", ".join(masses[:8]) + (f", ... ({len(masses)})" if len(masses) > 8 else "")
        coords = ", ".join(self.lin.coords[:8]) + (", ..." if n > 8 else "")
        return (f"all {n} mode(s) are rigid-body modes (0 Hz): no spring or shaft joins the masses ({shown}) "
                f"at this operating point, so nothing vibrates; they move in {n} rigid group(s), on the "
                f"coordinates {coords}, freely or against friction and damping only. Natural frequencies "
                f"need a compliance (a Spring, a Shaft, a tyre) between masses")

    def __str__(self) -> str:
        if self.all_rigid:
            return self.rigid_note()
        return "\n\n".join([str(self.frequency_table()), str(self.damped.table()), str(self.table())])


# ================================================================ undamped
def modal(lin, k: int | None = None, sigma: float = 0.0, rigid_tol: float = 1e-11) -> ModalResult:
    """Natural frequencies [Hz] and mass-normalised mode shapes of ``lin`` (undamped).

    ``k=None``: all modes (dense; up to ``DENSE_MAX`` coordinates). ``k``:
    the ``k`` modes nearest ``sigma`` [Hz] (the lowest ones for 0), by
    shift-invert Lanczos on the sparse matrices when the model is large.
    ``rigid_tol``: relative size of ``w^2`` (to the largest ``w^2``, or its
    Gershgorin bound) below which a mode is a rigid-body mode (0 Hz).
    """
    n = lin.n
    if n == 0:
        raise StructureError(f"model '{lin.compiled.model.name}' has no degree of freedom left to vibrate "
                             f"(every mass is fixed, driven or rigidly held)")
    if k is not None:
        k = int(k)
        if k < 1 or k > n:
            raise ParameterError(f"modal: k must be between 1 and the number of coordinates {n}, got {k}")
    if not np.isfinite(sigma) or sigma < 0:
        raise ParameterError(f"modal: sigma is a frequency in Hz (>= 0), got {sigma!r}")
    sigma2 = (2 * np.pi * sigma) ** 2
    _check_mass(lin)
    symmetric = _is_symmetric(lin.C)
    if k is None or n <= max(DENSE_SMALL, k + 2):
        if k is None and n > DENSE_MAX:
            raise ParameterError(f"modal: {n} coordinates are too many for all modes at once; give k (the number "
                                 f"of lowest modes wanted), e.g. modal(lin, k=20)")
        w2, phi, scale = _dense_modes(lin, symmetric)
        if k is not None:
            pick = np.sort(np.argsort(np.abs(w2 - sigma2), kind="stable")[:k])
            w2, phi = w2[pick], phi[:, pick]
    else:
        if not symmetric:
            raise ParameterError("modal: the stiffness matrix is not symmetric (a nonlinear law with coupled rows "
                                 "at this operating point); the partial solver needs symmetry: use k=None")
        w2, phi, scale = _sparse_modes(lin, k, sigma2)
    order = np.argsort(w2, kind="stable")
    w2, phi = w2[order], phi[:, order]
    rigid = np.abs(w2) <= rigid_tol * scale
    w2 = np.where(rigid, 0.0, w2)
    if np.any(w2 < 0):
        bad = np.nonzero(w2 < 0)[0] + 1
        warnings.warn(f"model '{lin.compiled.model.name}': mode(s) {bad.tolist()} have negative stiffness (w^2 < 0): "
                      f"the operating point is statically unstable; they are reported with |w|", stacklevel=2)
    phi = _normalise(lin, phi)
    return ModalResult(lin=lin, omega2=w2, shapes=phi, rigid=rigid, scale=scale, k=k, sigma=sigma)


def _dense(A) -> np.ndarray:
    return A.toarray() if sp.issparse(A) else np.asarray(A, float)


def _is_symmetric(A) -> bool:
    d = A - A.T
    num = abs(d).max() if sp.issparse(A) else np.abs(d).max(initial=0.0)
    den = abs(A).max() if sp.issparse(A) else np.abs(A).max(initial=0.0)
    return bool(num <= 1e-12 * max(den, 1e-300))


def _check_mass(lin) -> None:
    diag = lin.M.diagonal() if sp.issparse(lin.M) else np.diag(lin.M)
    bad = np.nonzero(~(diag > 0))[0]
    if len(bad):
        names = [lin.coords[i] for i in bad[:5]]
        raise StructureError(f"modal: coordinate(s) {names} have no mass in the structural-matrix form; "
                             f"put an inertia or mass there (regularity: devices join masses)")


def _dense_modes(lin, symmetric):
    M, C = _dense(lin.M), _dense(lin.C)
    try:
        if symmetric:
            w2, phi = la.eigh(C, M)
        else:
            w2, phi = la.eig(C, M)
            if np.abs(w2.imag).max(initial=0.0) > 1e-8 * np.abs(w2).max(initial=1.0):
                warnings.warn("modal: the stiffness matrix is not symmetric and some w^2 are complex (flutter-like "
                              "coupling); the undamped modes keep their real parts, see .damped for the true roots",
                              stacklevel=3)
            w2, phi = w2.real, phi.real
    except la.LinAlgError as exc:
        raise StructureError(f"modal: the mass matrix is not positive definite ({exc})") from None
    scale = float(np.abs(w2).max(initial=0.0)) or 1.0
    return w2, phi, scale


def _gershgorin_scale(lin) -> float:
    """Upper estimate of the largest ``w^2``: ``max_i sum_j |C_ij| / M_ii``."""
    C = sp.csr_matrix(lin.C)
    rows = np.asarray(abs(C).sum(axis=1)).ravel()
    m = sp.csr_matrix(lin.M).diagonal()
    return float(np.max(rows / m, initial=0.0)) or 1.0


def _shifted_lu(A, B, shift, scale, what):
    """LU of ``A - shift B``; moved by ``1e-9 scale`` when it is singular (a mode exactly at the shift)."""
    for s in (shift, shift - 1e-9 * scale, shift - 1e-6 * scale):
        try:
            lu = spla.splu(sp.csc_matrix(A - s * B))
        except RuntimeError:
            continue
        d = np.abs(lu.U.diagonal())
        if d.min() > 1e-13 * d.max():
            return lu, s
    raise StructureError(f"modal: could not factorise the shifted {what} matrix near {shift:g}")


def _sparse_modes(lin, k, sigma2):
    M, C = sp.csc_matrix(lin.M), sp.csc_matrix(lin.C)
    scale = _gershgorin_scale(lin)
    # a tiny negative offset keeps the factorisation regular when rigid-body modes sit at sigma = 0
    lu, shift = _shifted_lu(C, M, sigma2 - (1e-9 * scale if sigma2 == 0 else 0.0), scale, "stiffness")
    op = spla.LinearOperator(C.shape, matvec=lu.solve, dtype=float)
    v0 = np.random.default_rng(0).standard_normal(C.shape[0])
    w2, phi = spla.eigsh(C, k=k, M=M, sigma=shift, which="LM", OPinv=op, v0=v0, tol=0.0)
    return w2, phi, scale


def _normalise(lin, phi):
    """Mass-normalise; the largest full-coordinate entry of each mode positive."""
    M = lin.M
    mm = np.einsum("ij,ij->j", phi, M @ phi)
    phi = phi / np.sqrt(np.abs(mm))
    full = np.asarray(lin.T @ phi)
    idx = np.argmax(np.abs(full), axis=0)
    sign = np.sign(full[idx, np.arange(phi.shape[1])])
    return phi * np.where(sign == 0, 1.0, sign)


# ================================================================== damped
def damped_modes(lin, k: int | None = None, sigma: float = 0.0, n_rigid: int = 0,
                 scale: float | None = None) -> DampedModes:
    """Roots of ``(lambda^2 M + lambda B + C) u = 0`` by the companion form (see module docstring).

    One root per mode is kept (``Im lambda >= 0``; real roots of overdamped
    motions each count once), sorted by ``|lambda|``; the ``n_rigid``
    rigid-body modes appear as ``lambda = 0``. ``k``: the k roots nearest
    ``i 2 pi sigma`` (partial, sparse shift-invert Arnoldi for large models).
    """
    n = lin.n
    if scale is None:
        scale = _gershgorin_scale(lin)
    root_scale = np.sqrt(scale)
    if k is None and n > DAMPED_DENSE_MAX:
        raise ParameterError(f"damped modes: {n} coordinates are too many for all roots at once (a dense "
                             f"{2 * n} x {2 * n} eigenproblem); give k, e.g. modal(lin, k=20).damped")
    if k is None or n <= max(DAMPED_DENSE_SMALL, k + 2):
        A, E = _companion(lin, dense=True)
        lam, vec = la.eig(A, E)
    else:
        A, E = _companion(lin, dense=False)
        target = 1j * 2 * np.pi * sigma
        nev = min(2 * k + 2 * n_rigid + 2, 2 * n - 2)
        if sigma == 0:
            lu, s = _shifted_lu(A, E, -1e-9 * root_scale, root_scale, "companion")
            op = spla.LinearOperator(A.shape, matvec=lu.solve, dtype=float)
            lam, vec = spla.eigs(A, k=nev, M=E, sigma=s, OPinv=op, tol=0.0,
                                 v0=np.random.default_rng(0).standard_normal(A.shape[0]))
        else:
            lam, vec = spla.eigs(A.astype(complex), k=nev, M=E.astype(complex), sigma=target, tol=0.0)
    lam = np.asarray(lam, complex)
    vec = np.asarray(vec)[:n]
    if not np.all(np.isfinite(lam)):
        raise StructureError("damped_modes: non-finite eigenvalues (singular mass matrix?)")
    # defective double roots at 0 (undamped rigid modes) come out as +-sqrt(eps) noise
    zero = np.abs(lam) <= 1e-6 * root_scale
    lam = np.where(zero, 0.0, lam)
    tiny = np.abs(lam.imag) <= 1e-10 * np.maximum(np.abs(lam), root_scale * 1e-12)
    lam = np.where(tiny, lam.real, lam)
    if not (lin.B.nnz if sp.issparse(lin.B) else np.count_nonzero(lin.B)):
        lam = 1j * lam.imag      # no damping at all: the roots are exactly +-i w (round-off only in Re)
    keep = lam.imag >= 0
    lam, vec, zero = lam[keep], vec[:, keep], zero[keep]
    order = np.argsort(np.abs(lam), kind="stable")
    lam, vec, zero = lam[order], vec[:, order], zero[order]
    # a rigid mode has a double root at 0 without damping to ground and a single one with it
    nz = int(zero.sum())
    drop = np.nonzero(zero)[0][n_rigid:] if nz > n_rigid else np.zeros(0, int)
    mask = np.ones(len(lam), bool)
    mask[drop] = False
    lam, vec = lam[mask], vec[:, mask]
    if k is not None:
        if sigma:
            pick = np.sort(np.argsort(np.abs(lam - 1j * 2 * np.pi * sigma), kind="stable")[:k])
            lam, vec = lam[pick], vec[:, pick]
        else:
            lam, vec = lam[:k], vec[:, :k]
    norms = np.linalg.norm(vec, axis=0)
    vec = vec / np.where(norms > 0, norms, 1.0)
    return DampedModes(eigenvalues=lam, shapes=vec, rigid=(lam == 0))


def match_undamped(undamped: ModalResult, damped: DampedModes) -> np.ndarray:
    """The undamped mode each damped root belongs to (0-based; -1 if none is left).

    Pairs are taken greedily by the modal assurance criterion with the mass matrix,
    ``MAC = |phi^T M u|^2 / ((phi^T M phi)(u^H M u))``, highest first (ties: nearest natural
    frequency); each undamped mode takes one complex root (a pair, listed once) or up to two real roots
    (an overdamped mode, or a rigid one with damping to ground: 0 and the decay root).
    """
    phi, u = undamped.shapes, damped.shapes
    nd, nu = u.shape[1], phi.shape[1]
    index = np.full(nd, -1)
    if nd == 0 or nu == 0:
        return index
    M = undamped.lin.M
    Mphi = np.asarray(M @ phi)
    Mu = np.asarray(M @ u)
    num = np.abs(Mphi.T @ u) ** 2                                    # nu x nd (phi real)
    den = np.outer(np.einsum("ij,ij->j", phi, Mphi), np.real(np.einsum("ij,ij->j", u.conj(), Mu)))
    mac = num / np.where(den > 0, den, 1.0)
    fu = undamped.frequencies_hz
    fd = damped.natural_hz
    gap = np.abs(fu[:, None] - fd[None, :]) / max(float(np.max(fu, initial=0.0)), float(np.max(fd, initial=0.0)), 1e-300)
    order = np.lexsort((gap.ravel(), -np.round(mac.ravel(), 6)))
    capacity = np.full(nu, 2)
    has_zero = np.zeros(nu, bool)
    lam = damped.eigenvalues
    need = np.where(lam.imag > 0, 2, 1)
    for flat in order:
        i, j = divmod(int(flat), nd)
        if index[j] >= 0 or capacity[i] < need[j]:
            continue
        if lam[j] == 0 and (has_zero[i] or not undamped.rigid[i]):
            continue          # a rigid mode has one root at 0 (its partner is 0 too, or a decay root)
        index[j] = i
        capacity[i] -= need[j]
        has_zero[i] |= lam[j] == 0
    return index


def _companion(lin, dense: bool):
    n = lin.n
    if dense:
        M, B, C = _dense(lin.M), _dense(lin.B), _dense(lin.C)
        Z, I = np.zeros((n, n)), np.eye(n)
        return np.block([[Z, I], [-C, -B]]), np.block([[I, Z], [Z, M]])
    M, B, C = sp.csr_matrix(lin.M), sp.csr_matrix(lin.B), sp.csr_matrix(lin.C)
    I = sp.identity(n, format="csr")
    A = sp.bmat([[None, I], [-C, -B]], format="csc")
    E = sp.bmat([[I, None], [None, M]], format="csc")
    return A, E
