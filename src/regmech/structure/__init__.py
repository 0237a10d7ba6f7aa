"""Structure: regularity rules, nodes, Pantelides index reduction, dummy derivatives."""

from .pantelides import pantelides, structural_matching
from .regularity import check_model
from .system import MechanicalStructure, build_structure

__all__ = ["pantelides", "structural_matching", "check_model", "build_structure", "MechanicalStructure"]
