"""Pantelides' algorithm: which equations of a DAE must be differentiated.

Plain functions over a bipartite incidence (networkx style):

* ``equations``: mapping ``eq -> set of variables`` it contains;
* ``derivative``: mapping ``var -> var`` for the derivatives present
  (``x -> x'``). Variables without a derivative are the unknowns a matching
  may assign ("highest derivatives" and algebraic variables).

``pantelides`` returns how often each equation is differentiated so that
the differentiated system can be matched (structural index reduction, C. C.
Pantelides, SIAM J. Sci. Stat. Comput. 9 (1988) 213). Differentiating an
equation structurally replaces each variable ``v`` by ``{v, v'}``.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import networkx as nx
from networkx.algorithms import bipartite

from ..errors import StructureError


def structural_matching(equations: Mapping[Hashable, set]) -> tuple[dict, list, list]:
    """Maximum matching of equations to variables.

    Returns (matching eq->var, unmatched equations, unmatched variables).
    """
    g = nx.Graph()
    eq_nodes = [("e", e) for e in equations]
    g.add_nodes_from(eq_nodes, bipartite=0)
    variables = set().union(*equations.values()) if equations else set()
    g.add_nodes_from((("v", v) for v in variables), bipartite=1)
    g.add_edges_from((("e", e), ("v", v)) for e, vs in equations.items() for v in vs)
    m = bipartite.hopcroft_karp_matching(g, top_nodes=eq_nodes) if eq_nodes else {}
    match = {k[1]: val[1] for k, val in m.items() if k[0] == "e"}
    un_eq = [e for e in equations if e not in match]
    matched_vars = set(match.values())
    un_var = [v for v in variables if v not in matched_vars]
    return match, un_eq, un_var


def pantelides(equations: Mapping[Hashable, set], derivative: Mapping[Hashable, Hashable],
               max_order: int = 3) -> dict:
    """Differentiation count of every equation (0 for most).

    Raises ``StructureError`` when an equation can never be matched
    (structurally singular) or needs more than ``max_order`` differentiations.
    """
    eqs: dict = {e: set(vs) for e, vs in equations.items()}
    der: dict = dict(derivative)
    diff_of: dict = {}          # eq -> its derivative equation
    origin: dict = {e: (e, 0) for e in eqs}
    assign: dict = {}           # var -> eq

    def has_der(v):
        return v in der

    def augment(i, colored_e, colored_v) -> bool:
        colored_e.add(i)
        for j in eqs[i]:
            if not has_der(j) and j not in assign:
                assign[j] = i
                return True
        for j in eqs[i]:
            if not has_der(j) and j not in colored_v:
                colored_v.add(j)
                if augment(assign[j], colored_e, colored_v):
                    assign[j] = i
                    return True
        return False

    for k in list(eqs):
        i = k
        while True:
            ce, cv = set(), set()
            if augment(i, ce, cv):
                break
            for v in cv:
                der[v] = ("der", v)
            for e in ce:
                root, order = origin[e]
                if order + 1 > max_order:
                    raise StructureError(
                        f"equation {root!r} would need {order + 1} differentiations (index > {max_order}); "
                        f"the model is structurally singular or of unsupported index: check for loops of rigid "
                        f"devices or motion sources that over-constrain a mass")
                new = ("der", e)
                if new not in eqs:
                    eqs[new] = set(eqs[e]) | {der[v] for v in eqs[e] if v in der}
                    origin[new] = (root, order + 1)
                diff_of[e] = new
            for v in cv:
                assign[der[v]] = diff_of[assign[v]]
            i = diff_of[i]
    counts = {e: 0 for e in equations}
    for e, (root, order) in origin.items():
        counts[root] = max(counts[root], order)
    return counts
