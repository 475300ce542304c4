"""The two indirect force control (IFC) schemes a robot can be under, and their parameters."""

from dataclasses import dataclass

import numpy as np

__all__ = ['CARTESIAN_ADMITTANCE', 'JOINT_IMPEDANCE', 'CartesianAdmittance']

JOINT_IMPEDANCE = 'joint_impedance'
CARTESIAN_ADMITTANCE = 'cartesian_admittance'


@dataclass(frozen=True)
class CartesianAdmittance:
    """Cartesian admittance parameters h = M_x dd(x) + D_x d(x) + K_x x (docs/SPEC.md §1).

    Attributes:
        stiffness: K_x, 6 diagonal entries [N/m]*3 + [Nm/rad]*3.
        damping: D_x, 6 diagonal entries [Ns/m]*3 + [Nms/rad]*3.
        mass: M_x, 6 diagonal entries [kg]*3 + [kg m^2]*3.
    """

    stiffness: np.ndarray
    damping: np.ndarray
    mass: np.ndarray
