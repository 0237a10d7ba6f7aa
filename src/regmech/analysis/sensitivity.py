"""Sensitivity of natural frequencies to inertias and stiffnesses.

For a mass-normalised mode ``phi_i`` (``phi^T M phi = 1``) of
``C phi = w^2 M phi`` and a parameter p,

    d(w_i^2)/dp = phi_i^T (dC/dp - w_i^2 dM/dp) phi_i                  (1)

(exact for a simple eigenvalue). With ``M = T^T [m] T`` a body of inertia J
on full coordinate k gives ``dM/dJ = T^T e_k e_k^T T``, so
``d(w^2)/dJ = -w^2 (T phi)_k^2``. A compliant device gives
``dC/dp = (S T)^T dK_c/dp (S T)``, with ``dK_c/dp`` from its class kernel
(``compile.linear.stiffness_derivatives``). Then
``df/dp = d(w^2)/dp / (8 pi^2 f)`` [Hz per parameter unit] and the
logarithmic sensitivity ``(p/f) df/dp`` [-]: the % change of f per % of p.
Rigid-body modes (0 Hz) are left out. Repeated frequencies make (1)
ill-defined (any combination of their shapes is a mode): a warning says so.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..compile.linear import stiffness_derivatives
from .table import Table


@dataclass
class Sensitivities:
    """Frequency sensitivities: rows are the elastic modes, columns the parameters.

    ``parameters`` (``"J1.J"``, ``"spring.c"``), ``values`` (their values),
    ``modes`` (1-based mode numbers), ``frequencies_hz``, ``d_omega2``
    [rad^2/s^2 per unit], ``d_freq_hz`` [Hz per unit], ``relative`` [-].
    """

    parameters: list
    values: np.ndarray
    modes: list
    frequencies_hz: np.ndarray
    d_omega2: np.ndarray

    @property
    def d_freq_hz(self) -> np.ndarray:
        f = self.frequencies_hz[:, None]
        return self.d_omega2 / (8 * np.pi ** 2 * f)

    @property
    def relative(self) -> np.ndarray:
        return self.d_freq_hz * self.values[None, :] / self.frequencies_hz[:, None]

    def table(self, kind: str = "relative") -> Table:
        """``kind``: ``"relative"`` ((p/f) df/dp), ``"hz"`` (df/dp) or ``"omega2"`` (d(w^2)/dp)."""
        data = {"relative": self.relative, "hz": self.d_freq_hz, "omega2": self.d_omega2}.get(kind)
        if data is None:
            raise KeyError(f"Sensitivities.table: kind must be 'relative', 'hz' or 'omega2', got {kind!r}")
        title = {"relative": "relative sensitivity (p/f) df/dp", "hz": "df/dp [Hz per unit]",
                 "omega2": "d(w^2)/dp [rad^2/s^2 per unit]"}[kind]
        index = [f"mode {m} ({f:.4g} Hz)" for m, f in zip(self.modes, self.frequencies_hz)]
        return Table(data, index, self.parameters, title=title, index_name="mode")

    def to_dataframe(self, kind: str = "relative"):
        return self.table(kind).to_dataframe()

    def __str__(self) -> str:
        return str(self.table())


def sensitivities(result) -> Sensitivities:
    """Sensitivities (1) of the elastic modes of a ``ModalResult`` to every inertia and stiffness."""
    lin = result.lin
    elastic = np.nonzero(~result.rigid)[0]
    w2 = result.omega2[elastic]
    phi = result.shapes[:, elastic]
    full = np.asarray(lin.T @ phi)               # n x k
    labels, values, cols = [], [], []
    st = lin.compiled.structure
    for k, node in enumerate(st.coord_node):
        for b in node.bodies:
            labels.append(f"{b.name}.{b.mass_param}")
            values.append(b.mass)
            cols.append(-w2 * full[k] ** 2)
    s = np.asarray(lin.ST @ phi)                 # compliant rows x k
    for label, value, rows, rcols, dvals in stiffness_derivatives(lin):
        labels.append(label)
        values.append(value)
        cols.append(np.einsum("rk,r,rk->k", s[rows], dvals, s[rcols]))
    f = result.frequencies_hz[elastic]
    if len(f) > 1 and np.any(np.diff(np.sort(f)) <= 1e-8 * f.max()):
        warnings.warn("sensitivities: repeated natural frequencies; their sensitivities depend on the chosen "
                      "basis of the repeated modes and are not unique", stacklevel=2)
    data = np.array(cols).T.reshape(len(elastic), len(labels))
    return Sensitivities(parameters=labels, values=np.array(values, float), modes=[int(i) + 1 for i in elastic],
                         frequencies_hz=f, d_omega2=data)
