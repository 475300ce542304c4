"""Robot models: pinocchio kinematics plus IFC parameters, and the named configurations."""

from ifc_spg.model.ifc import CARTESIAN_ADMITTANCE, JOINT_IMPEDANCE, CartesianAdmittance
from ifc_spg.model.robot_model import RobotModel, robot_gains

__all__ = ['CARTESIAN_ADMITTANCE', 'JOINT_IMPEDANCE', 'CartesianAdmittance', 'RobotModel',
           'robot_gains']
