"""Exact response of a linear mass-spring-damper chain, independent of regmech's compiler.

A ``LinearChain`` is a list of masses (``Inertia`` or ``Mass``) and links
``(i, j, c, d)`` joining mass i to mass j (``j = None``: the ground) with a
spring c and a damper d in parallel, plus one prescribed torque/force on one
mass that is *piecewise linear in time* (a ramp, steps). It can build the
regmech model of itself (``to_model``) and, from its own hand-assembled
matrices, compute the exact motion (``exact``) of

    M x'' + D x' + K x = f(t),      f(t) = f0_k + f1_k (t - a_k) on [a_k, a_{k+1})

Method: the scaled first-order state of REFERENCES.md [002] (``L = M^1/2``,
``w = sqrt(||L^-1 K L^-1||_inf)`` an upper bound of the highest natural
frequency)::

    q = [L v, w L x],   q' = A q + B f,   A = [[-D^, -K^/w], [w I, 0]],  B = [L^-1; 0]

with ``D^ = L^-1 D L^-1``, ``K^ = L^-1 K L^-1``. Scaling keeps ``||A||`` at
the highest frequency instead of its square, so ``scipy.linalg.expm`` needs
few squarings even for a stretched spectrum. The affine forcing is carried by
two extra states ``[1, tau]`` (``tau = t - a_k``) of an augmented matrix, so
each step ``exp(A_aug dt)`` is exact for the forcing; one matrix exponential
per distinct step length and segment. Accuracy: round-off of the
exponentials (~1e-13 relative) times the number of steps.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la


@dataclass
class LinearChain:
    name: str
    masses: list[float]
    links: list[tuple[int, int | None, float, float]]
    load_mass: int                                  # index of the mass the source acts on
    load_segments: list[tuple[float, float, float]]  # (a_k, f0_k, f1_k): f = f0 + f1 (t - a_k) from a_k on
    x0: list[float] | None = None
    v0: list[float] | None = None
    translational: bool = False
    names: list[str] = field(default_factory=list)

    def __post_init__(self):
        n = len(self.masses)
        self.x0 = list(self.x0) if self.x0 is not None else [0.0] * n
        self.v0 = list(self.v0) if self.v0 is not None else [0.0] * n
        if not self.names:
            self.names = [f"m{i}" for i in range(n)]

    # ------------------------------------------------------------------ matrices
    def matrices(self):
        n = len(self.masses)
        M = np.diag(np.asarray(self.masses, float))
        K = np.zeros((n, n))
        D = np.zeros((n, n))
        for i, j, c, d in self.links:
            for mat, val in ((K, c), (D, d)):
                mat[i, i] += val
                if j is not None:
                    mat[j, j] += val
                    mat[i, j] -= val
                    mat[j, i] -= val
        return M, D, K

    def frequencies(self) -> np.ndarray:
        """Undamped natural frequencies [rad/s], ascending.

        With a stretched spectrum the eigenvalue solver's absolute error
        (eps times the largest eigenvalue) swamps the lowest frequency, so when K is
        regular the lowest one is taken from the flexibility matrix instead:
        ``omega_min^-2 = max eig(L^-1 ... )`` of ``M^1/2 K^-1 M^1/2`` (Cholesky solve)."""
        M, _, K = self.matrices()
        s = 1.0 / np.sqrt(np.diag(M))
        lam = la.eigvalsh(s[:, None] * K * s[None, :])
        w = np.sqrt(np.clip(lam, 0.0, None))
        try:
            with warnings.catch_warnings():         # ill-conditioned by design (stretched spectra)
                warnings.simplefilter("ignore", la.LinAlgWarning)
                flex = la.solve(K, np.diag(np.diag(M) ** 0.5), assume_a="pos")
            r = np.sqrt(np.diag(M))
            mu = la.eigvalsh(r[:, None] * flex)
            w[0] = 1.0 / np.sqrt(mu[-1])
        except (la.LinAlgError, ValueError):
            pass                            # rigid-body modes: K is singular, w[0] = 0 stays
        return w

    def force(self, t: float) -> float:
        seg = [s for s in self.load_segments if s[0] <= t]
        if not seg:
            return 0.0
        a, f0, f1 = seg[-1]
        return f0 + f1 * (t - a)

    # ------------------------------------------------------------------ regmech model
    def to_model(self, signal):
        """The regmech model of the chain; ``signal`` is the regmech signal of the load
        (it must equal ``force(t)``: the caller passes e.g. a ``Ramp``)."""
        import regmech as rm
        from regmech.components import Damper, Fixed, Force, Inertia, Mass, Spring, SpringDamper, Torque
        dom = "translational" if self.translational else "rotational"
        m = rm.Model(self.name)
        ground = m.add(Fixed("ground", domain=dom))
        bodies = []
        for i, (mass, nm) in enumerate(zip(self.masses, self.names)):
            if self.translational:
                bodies.append(m.add(Mass(nm, m=mass, s0=self.x0[i], v0=self.v0[i])))
            else:
                bodies.append(m.add(Inertia(nm, J=mass, phi0=self.x0[i], w0=self.v0[i])))
        for k, (i, j, c, d) in enumerate(self.links):
            if c > 0 and d > 0:
                dev = SpringDamper(f"link{k}", c=c, d=d, domain=dom)
            elif c > 0:
                dev = Spring(f"link{k}", c=c, domain=dom)
            else:
                dev = Damper(f"link{k}", d=d, domain=dom)
            m.add(dev)
            m.connect(dev.flange_a, ground.flange if j is None else bodies[j].flange_b)
            m.connect(dev.flange_b, bodies[i].flange_a)
        src = m.add(Force("load", f=signal) if self.translational else Torque("load", tau=signal))
        m.connect(src.flange, bodies[self.load_mass].flange_b)
        m.connect(src.support, ground.flange)
        return m

    # ------------------------------------------------------------------ exact solution
    def exact(self, times, digits: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (rows: times, columns: masses) at ascending ``times``.

        ``digits=None``: double precision on the scaled state (module docstring);
        its round-off grows about like the square of the frequency ratio (measured
        against 50-digit arithmetic: 3e-9 at a ratio of 1e5, 2e-5 at 1e7).
        ``digits=30`` (say): the same propagation in ``mpmath`` with that many
        decimal digits, on the unscaled state ``[x, v]`` (about a second per
        distinct step length for a dozen masses), for stretched spectra.
        """
        M, D, K = self.matrices()
        n = len(self.masses)
        li = 1.0 / np.sqrt(np.diag(M))
        e = np.zeros(n)
        e[self.load_mass] = 1.0
        x0 = np.asarray(self.x0, float)
        v0 = np.asarray(self.v0, float)
        A = np.zeros((2 * n + 2, 2 * n + 2))
        A[2 * n + 1, 2 * n] = 1.0                   # tau' = 1 (times the constant state)
        if digits is None:
            Dh = li[:, None] * D * li[None, :]
            Kh = li[:, None] * K * li[None, :]
            w = max(float(np.sqrt(np.max(np.sum(np.abs(Kh), axis=1)))), 1e-300)
            A[:n, :n] = -Dh
            A[:n, n:2 * n] = -Kh / w
            A[n:2 * n, :n] = w * np.eye(n)
            b = np.concatenate([li * e, np.zeros(n)])
            q0 = np.concatenate([v0 / li, w * x0 / li])

            def unpack(q):
                return li * q[n:2 * n] / w, li * q[:n]
            backend = _FloatBackend()
        else:
            minv = li ** 2
            A[:n, n:2 * n] = np.eye(n)
            A[n:2 * n, :n] = -minv[:, None] * K
            A[n:2 * n, n:2 * n] = -minv[:, None] * D
            b = np.concatenate([np.zeros(n), minv * e])
            q0 = np.concatenate([x0, v0])

            def unpack(q):
                return q[:n], q[n:2 * n]
            backend = _MpBackend(digits)
        times = np.asarray(times, float)
        bounds = sorted({seg[0] for seg in self.load_segments if seg[0] > times[0]})
        out_x = np.zeros((len(times), n))
        out_v = np.zeros((len(times), n))
        t = float(times[0])
        cache: dict = {}
        q = backend.vector(np.concatenate([q0, [1.0, 0.0]]))

        def segment_at(tt):
            seg = [sg for sg in self.load_segments if sg[0] <= tt]
            return seg[-1] if seg else (tt, 0.0, 0.0)

        def advance(q, t_from, t_to):
            a, f0, f1 = segment_at(t_from)
            key = (a, round((t_to - t_from) * 1e12))
            E = cache.get(key)
            if E is None:
                Aseg = A.copy()
                Aseg[:2 * n, 2 * n] = b * f0
                Aseg[:2 * n, 2 * n + 1] = b * f1
                E = cache[key] = backend.expm(Aseg, t_to - t_from)
            return backend.step(E, q, t_from - a)

        for k, tk in enumerate(times):
            while bounds and bounds[0] <= tk:        # cross a change of the forcing formula exactly
                q = advance(q, t, bounds[0])
                t = bounds.pop(0)
            if tk > t:
                q = advance(q, t, tk)
                t = float(tk)
            out_x[k], out_v[k] = unpack(backend.floats(q))
        return out_x, out_v


class _FloatBackend:
    def vector(self, z):
        return np.asarray(z, float)

    def expm(self, A, dt):
        return la.expm(A * dt)

    def step(self, E, q, tau0):
        z = q.copy()
        z[-2:] = (1.0, tau0)
        return E @ z

    def floats(self, q):
        return q


class _MpBackend:
    """mpmath at ``digits`` decimal digits (matrix entries from the doubles, exactly)."""

    def __init__(self, digits):
        self.digits = digits

    def _ctx(self):
        import mpmath
        return mpmath.workdps(self.digits)

    def vector(self, z):
        import mpmath
        with self._ctx():
            return mpmath.matrix([mpmath.mpf(float(v)) for v in z])

    def expm(self, A, dt):
        import mpmath
        with self._ctx():
            Am = mpmath.matrix([[mpmath.mpf(float(v)) for v in row] for row in A])
            return mpmath.expm(Am * mpmath.mpf(float(dt)))

    def step(self, E, q, tau0):
        import mpmath
        with self._ctx():
            z = q.copy()
            z[len(z) - 2] = mpmath.mpf(1)
            z[len(z) - 1] = mpmath.mpf(float(tau0))
            return E * z

    def floats(self, q):
        return np.array([float(v) for v in q], float)
