"""Robot models: pinocchio kinematics plus IFC parameters, and the named configurations."""

from ifc_spg.model.robot_model import (
    CARTESIAN_ADMITTANCE,
    JOINT_IMPEDANCE,
    CartesianAdmittance,
    RobotModel,
)

__all__ = ['CARTESIAN_ADMITTANCE', 'JOINT_IMPEDANCE', 'CartesianAdmittance', 'RobotModel']
