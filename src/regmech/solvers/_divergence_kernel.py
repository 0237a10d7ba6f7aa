"""numba kernel of the divergence test's per-step work (``divergence.GrowthWatch``); imported only by a run
whose right-hand side is compiled too (``compile.odeform``: numba is loaded already, so the check costs no
import).

One pass does what six numpy passes and two new arrays did: on 2,000 states the check of a step
cost 15 us with numpy, a tenth of a scipy DOP853 step of the chain of 1,000 inertias. The same arithmetic
in the same order (no fused multiply-add: no ``fastmath``), so the same numbers.

The largest ``|x|`` is taken on the bits: for a float that is not NaN, ``|x|`` orders as its bit pattern
with the sign cleared read as an integer, and every NaN reads above infinity. An integer maximum vectorises
(a floating-point one does not without ``fastmath``, which would also drop the NaN test).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_MAGNITUDE = 0x7FFFFFFFFFFFFFFF          # the bits of |x|
_INF_BITS = 0x7FF0000000000000           # above it: NaN


@njit(cache=True, inline="always")
def _magnitude(top):
    """The float whose bits are ``top`` (the largest ``|x|`` bits of a pass), inf when above infinity's: NaN."""
    if top > _INF_BITS:
        return math.inf
    return np.array([top], np.int64).view(np.float64)[0]


@njit(cache=True, error_model="numpy")
def step_check(u, u1, du1, factor, curvature, u_out, du_out, d):
    """``(N(u), max_j |d_j|)`` with ``N(u) = max_j |u_j|`` (inf when an entry is NaN, as
    ``divergence.state_norm``); ``du = u - u1`` into ``du_out`` and u into ``u_out``; with ``curvature``,
    ``d = du - du1 * factor`` into ``d`` (else the second value is 0). One pass over the entries (two
    had cost 15 us on 20,000 states, one costs 11)."""
    n = u.shape[0]
    bits = u.view(np.int64)
    top = 0
    if not curvature:
        for j in range(n):
            x = u[j]
            u_out[j] = x
            du_out[j] = x - u1[j]
            b = bits[j] & _MAGNITUDE
            top = b if b > top else top
        return _magnitude(top), 0.0
    top_d = 0
    d_bits = d.view(np.int64)
    for j in range(n):
        x = u[j]
        u_out[j] = x
        dx = x - u1[j]
        du_out[j] = dx
        dd = dx - du1[j] * factor
        d[j] = dd
        b = bits[j] & _MAGNITUDE
        top = b if b > top else top
        b = d_bits[j] & _MAGNITUDE
        top_d = b if b > top_d else top_d
    return _magnitude(top), _magnitude(top_d)
