"""Popov-Vereshchagin constrained hybrid dynamics with static friction (docs/SPEC.md §9–§10).

from ifc_spg.dynamics import VereshchaginSolver, StaticFrictionSolver
"""

from ifc_spg.dynamics.chain import Chain, chain_from_model
from ifc_spg.dynamics.static_friction import FrictionResult, SamplingResult, StaticFrictionSolver
from ifc_spg.dynamics.vereshchagin import VereshchaginResult, VereshchaginSolver

__all__ = [
    'Chain',
    'FrictionResult',
    'SamplingResult',
    'StaticFrictionSolver',
    'VereshchaginResult',
    'VereshchaginSolver',
    'chain_from_model',
]
