import pytest

from regmech.errors import StructureError
from regmech.structure import pantelides, structural_matching


def test_pendulum_constraint_is_differentiated_twice():
    # x' = u, y' = v, u' = lam x, v' = lam y - g, x^2 + y^2 = L^2  (index 3)
    eqs = {
        "e1": {"dx", "u"}, "e2": {"dy", "v"}, "e3": {"du", "lam", "x"}, "e4": {"dv", "lam", "y"},
        "e5": {"x", "y"},
    }
    der = {"x": "dx", "y": "dy", "u": "du", "v": "dv"}
    counts = pantelides(eqs, der)
    assert counts["e5"] == 2
    assert counts["e1"] + counts["e2"] >= 1          # one velocity equation differentiated once
    assert counts["e3"] == counts["e4"] == 0


def test_index_one_system_needs_nothing():
    eqs = {"e1": {"dx", "x", "z"}, "e2": {"z", "x"}}
    assert pantelides(eqs, {"x": "dx"}) == {"e1": 0, "e2": 0}


def test_structurally_singular_raises():
    eqs = {"e1": {"dx", "x"}, "e2": set()}
    with pytest.raises(StructureError):
        pantelides(eqs, {"x": "dx"})


def test_structural_matching_reports_unmatched():
    match, un_eq, un_var = structural_matching({"a": {"x"}, "b": {"x"}})
    assert len(un_eq) == 1 and un_var == []
