"""Strict-priority cascades of QPs: one interface (:class:`Cascade`), three solvers.

``daqp`` (:class:`~ifc_spg.cascade.daqp.DaqpCascade`, dual active set, exact, the default),
``proxsuite`` (:class:`~ifc_spg.cascade.proxsuite.ProxsuiteCascade`, dense proximal ALM,
for comparisons) and ``nullspace`` (:class:`~ifc_spg.cascade.nullspace.NullspaceCascade`,
the thesis' baseline: equality levels only, no torque-limit level). :func:`make_solver`
creates one by name.
"""

from types import ModuleType

import numpy as np

from ifc_spg.cascade.base import Cascade, CascadeResult, CascadeSolver, level_violation
from ifc_spg.cascade.daqp import DaqpCascade
from ifc_spg.cascade.nullspace import NullspaceCascade
from ifc_spg.cascade.proxsuite import ProxsuiteCascade
from ifc_spg.errors import SolverError, did_you_mean

__all__ = ['Cascade', 'CascadeResult', 'CascadeSolver', 'DaqpCascade', 'NullspaceCascade',
           'ProxsuiteCascade', 'SOLVERS', 'level_violation', 'make_solver']

SOLVERS = ('daqp', 'proxsuite', 'nullspace')


def make_solver(name: str, n: int, rho: float = 0.01, *, kernels: ModuleType | None = None,
                q_min: np.ndarray | None = None, q_max: np.ndarray | None = None) -> Cascade:
    """Create a cascade solver by name ('daqp', 'proxsuite' or 'nullspace').

    Args:
        name: The solver.
        n: Number of joints.
        rho: Regularization of qdot_v in each level (4.45).
        kernels: The kernels module of ``daqp`` (default :data:`ifc_spg.kernels.active`).
        q_min: Lower joint position limits [rad] of ``nullspace``'s joint clamping.
        q_max: Upper joint position limits [rad] of ``nullspace``'s joint clamping.
    """
    if name == 'daqp':
        return DaqpCascade(n, rho, kernels=kernels)
    if name == 'proxsuite':
        return ProxsuiteCascade(n, rho)
    if name == 'nullspace':
        return NullspaceCascade(n, rho, q_min=q_min, q_max=q_max)
    raise SolverError(f"unknown solver '{name}'{did_you_mean(name, SOLVERS)}; available: "
                      f"{', '.join(SOLVERS)}")
